"""gva's pick trials as a Gymnasium environment: ``gva/Pick-v0``.

Gymnasium 1.0 removed the entry-point plug-ins of Gym 0.2x, so an environment outside Gymnasium
is found by naming its module in the id, as ``ale_py`` does::

    import gymnasium
    env = gymnasium.make("sim.envs:gva/Pick-v0", task="selected-type")

(or ``import sim.envs`` first, then ``gymnasium.make("gva/Pick-v0", ...)``). Needs the ``gym``
extra: ``pip install -e '.[gym]'``. The environment is :class:`sim.envs.pick_env.PickEnv`.
"""

from __future__ import annotations

from gymnasium.envs.registration import register, registry

PICK_ID = "gva/Pick-v0"
"""The environment's Gymnasium id."""

if PICK_ID not in registry:
    # Without the PassiveEnvChecker gymnasium.make adds by default: when an env's first reset
    # raises (a refused option), that wrapper (Gymnasium 1.x) has marked its reset checked but
    # kept no observation, so every later step raised TypeError: cannot unpack NoneType. What it
    # checks (the spaces, reset and step's returns) the full gymnasium.utils.env_checker.check_env
    # checks in tests/sim/envs/test_pick_env.py; make(..., disable_env_checker=False) adds it.
    register(id=PICK_ID, entry_point="sim.envs.pick_env:PickEnv", disable_env_checker=True)
