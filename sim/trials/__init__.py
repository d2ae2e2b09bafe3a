"""Closed-loop pick trials and what they produce.

One trial (runner, plan inputs, execution, the oracle), its record and the scene it runs, GIFs
of trials, and datasets collected from demonstrations. Runs of many trials (the resumable loop,
run folders, statistics) are the run layer's: :mod:`harness`.
"""
