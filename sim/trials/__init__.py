"""Pick trials and what they produce.

One trial (runner, plan inputs, execution, the oracle), its record and the scene it runs, GIFs
of trials, and datasets collected from demonstrations; picks that re-predict while the arm
approaches have their own room, :mod:`sim.trials.closed_loop`. Runs of many trials (the
resumable loop, run folders, statistics) are the run layer's: :mod:`harness`.
"""
