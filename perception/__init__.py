"""Perception: the model interface, the KQV attention model and its baselines.

No simulator, no Pinocchio in here; a plug-in model needs only :mod:`perception.interface`.
"""
