"""``gva reproduce sim``: the paper's Table II, position error of every model in the simulator.

Every cell (model x task x training set size x training seed) trains a fresh model on the
first ``size`` scenes of its seed's training stream and is scored on its task's untrained test
scenes; cells run side by side, and a re-run skips the finished ones. The experiment, its
options and the run folder's layout: ``docs/reproducing.md``.

- :mod:`.settings`: what a run computes, and where its files go;
- :mod:`.jobs`: the work of the job pool: collecting datasets, computing cells;
- :mod:`.run`: a run, start to end; :mod:`.report` and :mod:`.figures`: its tables and plots.
"""
