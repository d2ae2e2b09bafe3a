"""``gva reproduce real``: the paper's Table III, YuMi picks out of 30 with trained models.

Per task and seed: oracle-verified demonstrations, a model trained on them, closed-loop pick
trials at untrained positions with the model in the loop (each model also under the run's
variants, darker light and the block by default, each paired with its clean trials), and GIFs
of the first trials; a re-run skips what is finished. The experiment,
its options and the run folder's layout: ``docs/reproducing.md``.

- :mod:`.settings`: what a run does, and where its files go;
- :mod:`.jobs`: the jobs (collect, train, trials, GIF); :mod:`.job_graph`: the graph that runs them;
- :mod:`.plugins`: plug-ins without weights, tried untrained beside the trained models;
- :mod:`.check_gate`: a checkpoint that failed its held-out check, not tried by default;
- :mod:`.gifs`: a model's first trials recorded again;
- :mod:`.run`: a run, start to end; :mod:`.folder` and :mod:`.report`: its tables.
"""
