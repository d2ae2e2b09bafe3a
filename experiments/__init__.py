"""Experiments: the paper's tables, sweeps and the gva command line."""
