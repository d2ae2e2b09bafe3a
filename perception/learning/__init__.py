"""Learning from demonstrations: what every trained model shares.

Datasets and their files, labels, the training loop, the held-out check, offline evaluation
and checkpoints.
"""
