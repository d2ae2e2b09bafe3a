"""The grasp judge: whether a predicted grasp would hold, judged without physics.

:mod:`~perception.judge.grasp_judge` measures a grasp's error in the true grasp's own frame
and predicts the pick; :mod:`~perception.judge.grasp_tolerance` reads the tolerance map it
judges against, ``grasp_tolerance.json`` beside it (measured by physics with
``benchmarks/bench_grasp_tolerance.py``; why: docs/decisions/grasp-judge.md). Numpy and the
catalog only, so an offline evaluation, a training's held-out check and a trial record all
judge alike.
"""
