"""Closed-loop picks (issue 36): the model re-predicts while the arm approaches.

:mod:`~sim.trials.closed_loop.loop` runs a pick's approach, looking again every
``1 / replan_hz`` s and re-targeting the arm where the grasp moved;
:mod:`~sim.trials.closed_loop.loop_settings` says what the loop is set to do (open or closed,
its rate and thresholds) and what its records keep, as data only, so run settings and reports
read them without the loop's machinery; :mod:`~sim.trials.closed_loop.view` says what a frame
shows of a target while the arm is in view (a demonstration's approach images are kept by it
too, :mod:`sim.trials.pick_images`). The trial runner (:mod:`sim.trials.trial_runner`) hands
an approach to the loop; the loop reads a pick's plan inputs, execution and records from the
rest of :mod:`sim.trials`.
"""
