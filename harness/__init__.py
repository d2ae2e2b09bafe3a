"""The run layer: what runs many picks and records them, between ``sim`` and ``experiments``.

Rooms, each importing only the ones before it (docs/design.md):

- a run's files: its folder (:mod:`.run_folder`), provenance (:mod:`.provenance`), the
  summary of its records (:mod:`.trial_summary`), the trial log (:mod:`.trial_log`), JSON and
  error files of its jobs and the datasets it reuses (:mod:`.run_files`);
- statistics over runs: paired comparisons (:mod:`.paired_statistics`, :mod:`.compare`), the
  grasp judge over a run's records (:mod:`.calibration`, :mod:`.judging`);
- jobs and where they run: the local pool (:mod:`.jobs`), Ray (:mod:`.ray_jobs`), choosing one
  (:mod:`.executors`);
- runs: the resumable loop of pick trials (:mod:`.run_loop`), a run's progress bar and what it
  did (:mod:`.run_report`).

``harness`` imports ``sim``, ``control``, ``perception`` and ``robots``; ``sim`` never imports it.
"""
