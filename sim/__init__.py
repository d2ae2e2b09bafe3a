"""The simulated YuMi scene on PyBullet: world, robot, head camera and the object catalog.

``sim`` may import ``control`` (pure kinematics) and ``perception``'s interface and data, never
``experiments``. Every world owns its own PyBullet client, so several can live in one process.
"""

from sim.world import quiet as _quiet  # noqa: F401  (first: swallows PyBullet's banner)
