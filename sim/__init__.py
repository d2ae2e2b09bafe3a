"""The simulated YuMi on PyBullet, in three rooms, each importing only the ones before it.

``world/``: the YuMi scene and the paper's, the robot, the head camera, the object catalog.
``tasks/``: task specs and their TOML files, the two scenes, seeded scene sampling.
``trials/``: the closed-loop trial runner, runs of trials and their records, GIFs, datasets.

``sim`` may import ``control`` (pure kinematics) and ``perception``'s interface and data, never
``experiments``. Every world owns its own PyBullet client, so several can live in one process.
"""

from sim.world import quiet as _quiet  # noqa: F401  (first: swallows PyBullet's banner)
