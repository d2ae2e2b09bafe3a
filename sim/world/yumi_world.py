"""The headless PyBullet scene: checker floor, wooden table, a robot, catalog objects."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
import pybullet

from perception.objects.catalog import ObjectSpec, PrimitiveKind
from perception.poses import Pose, rot_z
from robots.description import RobotDescription
from sim.errors import InvalidInputError, SimulationError
from sim.world.bullet_world import TABLE_TOP_Z_IN_URDF_M, BulletWorld
from sim.world.looks import ObjectLook, dress_object, dress_table
from sim.world.sim_robot import SimRobot
from sim.world.world_config import MAX_WAIT_S, TABLE_HALF_SIZE_M, WorldConfig, check_wait_s

StepHook = Callable[["World"], None]
"""Called with the world after each physics step (see :attr:`World.step_hook`)."""
REST_SPEED_M_S, REST_SPEED_RAD_S = 1e-3, 1e-2
"""Below both, :meth:`World.sleep_resting_objects` takes an object to be at rest."""
class World(BulletWorld[ObjectSpec]):
    """One headless PyBullet world with ``robot`` at the origin on a table top at z = 0.

    Use it as a context manager, or call :meth:`close`. :meth:`reset_scene` keeps the client
    and the robot and only removes the objects; :meth:`rebuild` starts the physics afresh (a
    trial does, so that it depends on no earlier one).
    """

    def __init__(self, config: WorldConfig | None = None, *,
                 robot: RobotDescription) -> None:
        self.config = WorldConfig() if config is None else config
        self.config.check_robot(robot)
        self.description = robot  # the robot standing at the origin
        self.step_hook: StepHook | None = None
        """Called after every physics step (e.g. to record frames); None, the default, costs
        nothing."""
        self.client = None
        self._build()

    def _build(self) -> None:
        """Connects a PyBullet client and loads the floor, the table and the robot."""
        client = self._connect(self.config.time_step_s, self.config.gravity_m_s2)
        client.setPhysicsEngineParameter(numSolverIterations=self.config.solver_iterations)
        cx, cy = self.config.table_center_xy_m
        self.plane_id = int(client.loadURDF("plane.urdf", [0.0, 0.0, -TABLE_TOP_Z_IN_URDF_M]))
        self.table_id = int(client.loadURDF(
            "table/table.urdf", [cx, cy, -TABLE_TOP_Z_IN_URDF_M], useFixedBase=True
        ))
        robot_id = int(client.loadURDF(
            str(self.description.urdf_path), [0.0, 0.0, 0.0], useFixedBase=True,
            flags=pybullet.URDF_USE_INERTIA_FROM_FILE,
        ))
        self.steps = 0
        self._objects: dict[int, ObjectSpec] = {}
        self._shapes: dict[ObjectSpec, tuple[int, int]] = {}
        self._sliding: dict[int, tuple[float, float]] = {}
        self.robot = SimRobot(client, robot_id, self.config.robot, step=self.step,
                              robot=self.description)

    def rebuild(self) -> None:
        """Starts the physics afresh, as :meth:`__init__` made it (the step hook is kept).

        What happens next then depends on nothing an earlier use left behind: PyBullet's
        contact caches and solver warm starts, the ids and order of bodies added and removed.
        A trial starts here (about 0.1 s), so its record is the same however the run went.
        """
        self.close()
        self._build()

    @property
    def time_s(self) -> float:
        """Simulated time since the world was made or last reset [s]."""
        return self.steps * self.config.time_step_s

    def step(self, n: int = 1) -> None:
        """Advance the physics by ``n`` steps, at most ``MAX_WAIT_S`` of simulated time."""
        most = round(MAX_WAIT_S / self.config.time_step_s)
        if not 0 <= n <= most:
            raise InvalidInputError("n", n, f"a number of steps in [0, {most}] ({MAX_WAIT_S} s)")
        for _ in range(n):
            self.robot.before_step()
            for body, (vx, vy) in self._sliding.items():  # carried as on a belt: see keep_sliding
                vz = self.client.getBaseVelocity(body)[0][2]
                self.client.resetBaseVelocity(body, [vx, vy, vz], [0.0, 0.0, 0.0])
            self.client.stepSimulation()
            self.steps += 1
            if self.step_hook is not None:
                self.step_hook(self)

    def add_object(
        self, spec: ObjectSpec, position_xy_m: tuple[float, float], yaw_rad: float,
        look: ObjectLook | None = None,
    ) -> int:
        """Place an object resting on the table at ``position_xy_m`` turned by ``yaw_rad``.

        ``look``: its colours and texture (:mod:`sim.world.looks`); None: the catalog's.
        """
        x, y = (float(v) for v in position_xy_m)
        self._check_on_table("position_xy_m", (x, y), (x, y))
        collision, visual = self._shape_ids(spec)
        body = int(self.client.createMultiBody(
            baseMass=spec.mass_kg, baseCollisionShapeIndex=collision,
            baseVisualShapeIndex=visual, basePosition=[x, y, 0.0],
            baseOrientation=self.client.getQuaternionFromEuler([0.0, 0.0, float(yaw_rad)]),
            baseInertialFramePosition=spec.center_of_mass_m.tolist(),
        ))
        if body < 0:
            raise SimulationError(f"PyBullet could not create a body for {spec.name!r}")
        self.client.changeDynamics(
            body, -1, lateralFriction=spec.lateral_friction,
            spinningFriction=spec.spinning_friction_m, rollingFriction=spec.rolling_friction_m,
            restitution=0.0, activationState=pybullet.ACTIVATION_STATE_ENABLE_SLEEPING
            if self.config.object_sleeping else pybullet.ACTIVATION_STATE_DISABLE_SLEEPING,
        )
        self._objects[body] = spec
        if look is not None:
            dress_object(self.client, body, spec, look)
        return body

    def dress_table(self, name: str) -> None:
        """Gives the table top the finish called ``name`` (:data:`sim.world.looks.TABLE_LOOKS`).

        Until :meth:`rebuild`, which brings back the URDF's wood.
        """
        dress_table(self.client, self.table_id, name)

    def on_table(self, xy: Any) -> bool:
        """Whether ``xy`` [m] is where :meth:`add_object` places objects: 5 cm inside the top."""
        (cx, cy), (hx, hy) = self.config.table_center_xy_m, TABLE_HALF_SIZE_M
        return bool(abs(xy[0] - cx) <= hx - 0.05 and abs(xy[1] - cy) <= hy - 0.05)

    def _check_on_table(self, field: str, value: Any, xy: tuple[float, float],
                        moved: str = "") -> None:
        """Raises unless ``xy`` is :meth:`on_table`."""
        (cx, cy), (hx, hy) = self.config.table_center_xy_m, TABLE_HALF_SIZE_M
        if not self.on_table(xy):
            raise InvalidInputError(field, value, f"{moved}on the table, x {cx - hx + 0.05}.."
                                    f"{cx + hx - 0.05} m, y {cy - hy + 0.05}..{cy + hy - 0.05} m")

    def move_object(self, body_id: int, dx_m: float, dy_m: float, dyaw_rad: float,
                    settle_s: float = 0.25) -> Pose:
        """Teleport and settle: moves an object on the table by (dx, dy) and turns it by dyaw.

        The object frame (:meth:`object_pose`: footprint centre, z up) is lifted 2 mm, moved by
        ``(dx_m, dy_m)`` and turned by ``dyaw_rad`` about the world vertical through its
        footprint centre, its velocities zeroed and it woken; then the world steps ``settle_s``
        so it drops the 2 mm and rests on the table again (a push's path is not simulated:
        nothing it would have brushed against on the way is disturbed). Returns its new pose.

        Raises:
            InvalidInputError: An unknown body, a value that is not finite, a ``settle_s``
                outside [0, MAX_WAIT_S], or a move that leaves the table area
                :meth:`add_object` allows (field ``dx_m, dy_m``).

        """
        spec = self.object_spec(body_id)
        for name, value in (("dx_m", dx_m), ("dy_m", dy_m), ("dyaw_rad", dyaw_rad)):
            if not math.isfinite(value):
                raise InvalidInputError(name, value, "a finite number")
        check_wait_s("settle_s", settle_s)
        pose = self.object_pose(body_id)
        x, y, z = (float(v) for v in pose.position)
        self._check_on_table("dx_m, dy_m", (dx_m, dy_m), (x + dx_m, y + dy_m),
                             f"a move that keeps the object ({x:.3f}, {y:.3f} m) ")
        origin = np.array([x + dx_m, y + dy_m, z + 0.002])
        rotation = rot_z(dyaw_rad) @ pose.rotation
        _, quaternion = self.client.multiplyTransforms(  # the turn, then the object's rotation
            [0.0, 0.0, 0.0], self.client.getQuaternionFromEuler([0.0, 0.0, dyaw_rad]),
            [0.0, 0.0, 0.0], self.client.getBasePositionAndOrientation(body_id)[1])
        self.client.resetBasePositionAndOrientation(  # PyBullet's base is the centre of mass
            body_id, (origin + rotation @ spec.center_of_mass_m).tolist(), quaternion)
        self.client.resetBaseVelocity(body_id, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0])
        self.client.changeDynamics(body_id, -1, activationState=pybullet.ACTIVATION_STATE_WAKE_UP)
        self.step(round(settle_s / self.config.time_step_s))
        return self.object_pose(body_id)

    def robot_gap_m(self, body_id: int, within_m: float) -> float:
        """How near an object comes to the robot [m]; ``within_m`` where it is no nearer."""
        self.object_spec(body_id)  # an unknown body is refused, naming it
        points = self.client.getClosestPoints(body_id, self.robot.body_id, within_m)
        return min((float(point[8]) for point in points), default=within_m)

    def move_object_if(self, body_id: int, dx_m: float, dy_m: float, dyaw_rad: float,
                       keep: Callable[[], bool]) -> Pose | None:
        """:meth:`move_object` without settling, kept only where ``keep()`` says so then.

        Where ``keep()``, asked with the object moved, is False, the object goes back exactly as
        it was (pose and velocities), and None is returned; else its new pose.
        """
        client = self.client
        position, orientation = client.getBasePositionAndOrientation(body_id)
        linear, angular = client.getBaseVelocity(body_id)
        moved = self.move_object(body_id, dx_m, dy_m, dyaw_rad, settle_s=0.0)
        if keep():
            return moved
        client.resetBasePositionAndOrientation(body_id, position, orientation)
        client.resetBaseVelocity(body_id, linear, angular)
        return None

    def keep_sliding(self, body_id: int, velocity_xy_m_s: tuple[float, float]) -> None:
        """Carries an object across the table at a steady velocity, as a conveyor belt would.

        Until :meth:`stop_sliding`, every :meth:`step` sets its horizontal velocity to
        ``velocity_xy_m_s`` [m/s] (and its spin to zero; gravity and contacts keep its
        vertical motion), and its friction is off: a belt moving under it drags it along,
        so the table's friction must not hold it back (with friction on, a velocity set
        before each step moved a sponge 0.5 mm, not 25 mm, in 0.5 s at 0.05 m/s: the step's
        friction impulse stops it). It does not sleep meanwhile. Call :meth:`stop_sliding`
        before the fingers close on it: an object without friction cannot be held, and a
        carried one pushes against the grip.
        """
        self.object_spec(body_id)
        vx, vy = (float(v) for v in velocity_xy_m_s)
        if not (math.isfinite(vx) and math.isfinite(vy)):
            raise InvalidInputError("velocity_xy_m_s", (vx, vy), "two finite numbers [m/s]")
        self.client.changeDynamics(
            body_id, -1, lateralFriction=0.0, spinningFriction=0.0, rollingFriction=0.0,
            activationState=pybullet.ACTIVATION_STATE_DISABLE_SLEEPING)
        self.client.changeDynamics(body_id, -1, activationState=pybullet.ACTIVATION_STATE_WAKE_UP)
        self._sliding[body_id] = (vx, vy)

    def stop_sliding(self, body_id: int) -> None:
        """Stops :meth:`keep_sliding`: the object stops with the belt, its friction restored.

        Its horizontal velocity and spin are zeroed; nothing happens to an object not sliding.
        """
        spec = self.object_spec(body_id)
        if self._sliding.pop(body_id, None) is None:
            return
        vz = self.client.getBaseVelocity(body_id)[0][2]
        self.client.resetBaseVelocity(body_id, [0.0, 0.0, vz], [0.0, 0.0, 0.0])
        self.client.changeDynamics(
            body_id, -1, lateralFriction=spec.lateral_friction,
            spinningFriction=spec.spinning_friction_m, rollingFriction=spec.rolling_friction_m,
            activationState=pybullet.ACTIVATION_STATE_ENABLE_SLEEPING
            if self.config.object_sleeping else pybullet.ACTIVATION_STATE_DISABLE_SLEEPING)

    def sleep_resting_objects(self) -> None:
        """Puts every object at rest to sleep now, rather than after Bullet's 2 s of stillness.

        At rest: slower than 1 mm/s and 0.01 rad/s. A moving object stays awake; nothing
        happens where :attr:`~sim.world.world_config.WorldConfig.object_sleeping` is off.
        """
        if not self.config.object_sleeping:
            return
        for body in self._objects:
            if body in self._sliding:
                continue
            linear, angular = self.client.getBaseVelocity(body)
            if np.linalg.norm(linear) < REST_SPEED_M_S and \
                    np.linalg.norm(angular) < REST_SPEED_RAD_S:
                self.client.changeDynamics(body, -1,
                                           activationState=pybullet.ACTIVATION_STATE_SLEEP)

    def remove_object(self, body_id: int) -> None:
        """Take an object out of the world."""
        self.object_spec(body_id)
        self._sliding.pop(body_id, None)
        self.client.removeBody(body_id)
        del self._objects[body_id]

    def object_spec(self, body_id: int) -> ObjectSpec:
        """Look up the catalog entry of an object in the world."""
        try:
            return self._objects[body_id]
        except KeyError:
            known = ", ".join(map(str, self._objects)) or "none"
            allowed = f"an object in this world: {known}"
            raise InvalidInputError("body_id", body_id, allowed) from None

    def object_pose(self, body_id: int) -> Pose:
        """``T_world_object``: the object frame (footprint centre, z up) in the world."""
        spec = self.object_spec(body_id)
        position, quaternion = self.client.getBasePositionAndOrientation(body_id)
        rotation = np.array(self.client.getMatrixFromQuaternion(quaternion)).reshape(3, 3)
        # PyBullet reports the centre of mass; the object frame lies back along -com.
        return Pose(np.array(position) - rotation @ spec.center_of_mass_m, rotation)

    def object_bottom_z_m(self, body_id: int) -> float:
        """Height of the object's lowest point above the table [m] (from its bounding box)."""
        self.object_spec(body_id)
        return float(self.client.getAABB(body_id)[0][2])

    def reset_scene(self, q_by_name: Mapping[str, float] | None = None) -> None:
        """Remove every object and teleport the robot to ``q_by_name`` (None: home) at rest."""
        for body in list(self._objects):
            self.remove_object(body)
        self.robot.reset(self.description.home if q_by_name is None else q_by_name)
        self.steps = 0

    def _shape_ids(self, spec: ObjectSpec) -> tuple[int, int]:
        """Collision and visual shapes of a spec, made once per world and shared by its bodies."""
        if spec not in self._shapes:
            kinds = [
                pybullet.GEOM_BOX if p.kind is PrimitiveKind.BOX else pybullet.GEOM_CYLINDER
                for p in spec.primitives
            ]
            geometry: dict[str, Any] = {
                "shapeTypes": kinds,
                "halfExtents": [[s / 2 for s in p.size_m] for p in spec.primitives],
                "radii": [p.size_m[0] / 2 for p in spec.primitives],
                "lengths": [p.size_m[2] for p in spec.primitives],
            }
            positions = [list(p.position_m) for p in spec.primitives]
            orientations = [self.client.getQuaternionFromEuler(p.rpy_rad) for p in spec.primitives]
            collision = self.client.createCollisionShapeArray(
                **geometry, collisionFramePositions=positions,
                collisionFrameOrientations=orientations,
            )
            visual = self.client.createVisualShapeArray(
                **geometry, visualFramePositions=positions, visualFrameOrientations=orientations,
                rgbaColors=[list(p.rgba) for p in spec.primitives],
            )
            if collision < 0 or visual < 0:
                raise SimulationError(f"PyBullet could not create the shapes of {spec.name!r}")
            self._shapes[spec] = (int(collision), int(visual))
        return self._shapes[spec]
