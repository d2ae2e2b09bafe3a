"""The ``gva`` commands, one module each: its options and what it prints.

An option's default is read from the settings dataclass the command fills, so each default has
one home. :mod:`experiments.cli` imports a command's module only when that command is parsed:
``gva --help`` loads neither pinocchio nor torch, and ``gva trials`` no torch.
"""
