"""Closed-loop pick trials and what they produce.

One trial (runner, plan inputs, execution, the oracle), runs of trials (the resumable loop, its
records), GIFs of trials, and datasets collected from demonstrations.
"""
