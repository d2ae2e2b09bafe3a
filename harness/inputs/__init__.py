"""What a run is made of: the trials it runs and the datasets it trains on.

:class:`~harness.inputs.trial_settings.TrialSettings` is a run of trials' identity, inputs and
held-out check; :func:`~harness.inputs.collector.collect` makes the datasets a run trains on
(demonstrations and labelled scene sets). The run layer's first room: the rest of
:mod:`harness` reads a run's identity from here, and :mod:`sim` below knows nothing of runs (it
is one pick).
"""
