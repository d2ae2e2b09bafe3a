"""The simulated YuMi on PyBullet: one pick, in rooms, each importing only the ones before it.

``errors``: the errors every room raises.
``world/``: the YuMi scene and the paper's, the robot, the head camera, the object catalog.
``tasks/``: task specs and their TOML files, the two scenes, seeded scene sampling.
``trials/``: one pick: the closed-loop trial runner, its record, GIFs, datasets.
``envs/``: the Gymnasium environment over one pick.

``sim`` may import ``control`` (pure kinematics) and ``perception``'s interface and data, never
``harness`` (runs of many picks) or ``experiments``. Every world owns its own PyBullet client,
so several can live in one process.
"""

from sim.world import quiet as _quiet  # noqa: F401  (first: swallows PyBullet's banner)
