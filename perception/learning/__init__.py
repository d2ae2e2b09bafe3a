"""Learning from demonstrations: what every trained model shares.

Datasets and their files, the training loop, the torch pieces and rotation codes every network
uses, the held-out check, offline evaluation and checkpoints. The label layout is
:mod:`perception.labels`; no module here imports :mod:`perception.models`.
"""
