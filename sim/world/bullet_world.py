"""What each PyBullet world of the simulator owns: a headless client, connected and closed once.

:class:`BulletWorld` connects a DIRECT client (PyBullet's chatter silenced) with pybullet_data's
models, the world's time step and gravity, and closes it, also as a context manager. The
paper's scene (:class:`~sim.world.paper_world.PaperWorld`) and the robot's
(:class:`~sim.world.yumi_world.World`) both stand on it: each then loads its floor, table and
bodies.
"""

from __future__ import annotations

from collections.abc import Mapping
from types import TracebackType
from typing import Any, Generic, Self, TypeVar

import pybullet
import pybullet_data
from pybullet_utils import bullet_client

from sim.world.quiet import silenced_output

TABLE_TOP_Z_IN_URDF_M = 0.625
"""Height of ``table/table.urdf``'s top surface in its own frame [m]."""
Placed = TypeVar("Placed")
"""What a world knows of each object it placed: a type's name, or its catalog spec."""


class BulletWorld(Generic[Placed]):
    """A world that owns one PyBullet client and the objects placed in it.

    :meth:`_connect` makes the client, :meth:`close` ends it; the subclass places the objects.
    """

    client: Any
    """The PyBullet client; None once closed."""
    _objects: dict[int, Placed]
    """The objects placed in the world: body id -> what it is; kept by the subclass."""

    @property
    def objects(self) -> Mapping[int, Placed]:
        """The objects in the world: body id -> what it is (a copy)."""
        return dict(self._objects)

    def _connect(self, time_step_s: float, gravity_m_s2: float) -> Any:
        """Connects a fresh client as :attr:`client`, and returns it.

        With pybullet_data's models, ``time_step_s`` [s] and gravity ``gravity_m_s2`` along -z.
        """
        with silenced_output():  # PyBullet prints "argv[0]=" from C on every connect
            self.client = bullet_client.BulletClient(connection_mode=pybullet.DIRECT)
        self.client.setAdditionalSearchPath(pybullet_data.getDataPath())
        self.client.setTimeStep(time_step_s)
        self.client.setGravity(0.0, 0.0, -gravity_m_s2)
        return self.client

    def close(self) -> None:
        """Disconnects the PyBullet client; the world is unusable afterwards."""
        if self.client is not None:
            self.client.disconnect()
            self.client = None

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self, kind: type[BaseException] | None, error: BaseException | None,
        trace: TracebackType | None,
    ) -> None:
        self.close()
