"""One pick trial in the ``yumi`` scene: set up, then for each target: sense, predict, plan, run.

For a task with several targets (``multiple``) the robot picks them one after another. Before
each pick it takes a fresh image and asks the model again; each picked object is set aside
(taken off the table) after its lift and hold, and the arm returns to its start. A trial
succeeds when every target was picked. A model may omit targets it has already seen picked:
its predictions are matched to the task's targets from the end (the oracle returns only the
objects still on the table; a learned model with one head per target returns all of them).

The robot acts on perception alone. A pick's plan phase (:meth:`TrialRunner.plan_pick`) gets
the head camera's RGB-D frame with its calibration, the robot's joint state, the table (a
fixed, known fixture) and the model's prediction: the grip comes from the type or opening the
model stated (:mod:`sim.world.grip`), the obstacles from the depth image
(:mod:`control.depth_obstacles`). The simulator's truth judges: the referee notes the target's
true grasp when the image is taken, as a dataset labels its images, and the physics decides
the outcome; neither is handed to the plan phase.
"""

from __future__ import annotations

import dataclasses
import time
import traceback
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import pinocchio as pin

from control.collision import AnyObstacle
from control.depth_obstacles import DepthObstacleConfig, GraspRegion, depth_obstacles
from control.pick import PickPlan, PickRequest, PlanStatus
from control.planner import PickPlanner
from perception.camera import RgbdFrame
from perception.interface import PerceptionError, PerceptionModel, Prediction, Target
from perception.labels import nearest_rotation
from robots import yumi
from sim.errors import InvalidInputError, SimError
from sim.tasks.scene_sampling import Scene
from sim.tasks.task_spec import TaskSpec
from sim.trials.execution import ExecutionSettings, execute_pick
from sim.trials.oracle import OraclePerception
from sim.trials.planner_setup import (
    ObstacleSource,
    make_yumi_planner,
    nearest_object,
    object_obstacles,
    table_obstacle,
    yumi_depth_config,
)
from sim.trials.records import TrialOutcome, TrialRecord
from sim.world.catalog import Pose, clear_of_table, get_object_spec
from sim.world.grasps import grasp_pose
from sim.world.grip import Grip, grip_of
from sim.world.head_camera import HeadCamera
from sim.world.yumi_world import World

_PLAN_OUTCOMES = {
    PlanStatus.UNREACHABLE: TrialOutcome.IK_UNREACHABLE,
    PlanStatus.COLLISION: TrialOutcome.PLAN_COLLISION,
    PlanStatus.START_IN_COLLISION: TrialOutcome.PLAN_COLLISION,
}


class TrialObserver(Protocol):
    """Watches trials as they run, e.g. to record them (:mod:`sim.trials.gif_recorder`).

    Watching must not change what happens: an observer reads the world, never moves it.
    """

    def saw(self, image: np.ndarray, prediction: Prediction) -> None:
        """The image (H, W, 3) a pick's prediction was made from, and the prediction."""

    def stepped(self, world: World) -> None:
        """Called after every physics step of the runner's world."""


def pose_json(position: np.ndarray, rotation: np.ndarray | None) -> dict[str, Any]:
    """A pose as rounded JSON-able lists."""
    data: dict[str, Any] = {"position_m": [round(float(v), 6) for v in position]}
    if rotation is not None:
        data["rotation"] = [[round(float(v), 6) for v in row] for row in rotation]
    return data


def rotation_error_rad(truth: np.ndarray, predicted: np.ndarray) -> float:
    """Angle between two TCP orientations, counting the gripper's half-turn symmetry."""
    flip = np.diag([-1.0, -1.0, 1.0])
    return min(float(np.linalg.norm(pin.log3(truth.T @ predicted @ f))) for f in (np.eye(3), flip))


@dataclass(frozen=True)
class PlannedPick:
    """The plan phase of one pick: what the robot decided from its sensors and the model.

    Args:
        fields: What the pick's record keeps of it (prediction, grip, obstacles, plan status).
        grip: How the gripper closes; None if the prediction gave no usable target.
        plan: The plan to run; None when the pick ends here.
        outcome: Why the pick ends here (a perception or planning failure); None with a plan.
        reason: The failure's reason.

    """

    fields: dict[str, Any]
    grip: Grip | None = None
    plan: PickPlan | None = None
    outcome: TrialOutcome | None = None
    reason: str = ""


@dataclass(frozen=True)
class PickReport:
    """One finished pick: its record fields (outcome included) and the plan that ran, if any."""

    fields: dict[str, Any]
    plan: PickPlan | None

    @property
    def outcome(self) -> TrialOutcome:
        """How the pick ended."""
        return self.fields["outcome"]


class TrialRunner:
    """One world, camera, model and planner, reused across the trials of a run.

    Args:
        task: The task the scenes are drawn from.
        model: Builds the perception model from the world and camera (e.g. the oracle).
        settle_s: Time objects settle on the table before the first image [s].
        execution: How picks are executed and judged.
        planner: The pick planner; the YuMi's when None.
        observer: Sees every prediction and every physics step; None (the default) costs
            nothing.
        obstacles: What picks are planned around besides the table: the depth image (the
            default), or the simulator's true shapes (for debugging the planner only).
        depth: How depth points become obstacles; the YuMi workcell's when None.

    """

    def __init__(
        self,
        task: TaskSpec,
        model: Any = OraclePerception,
        settle_s: float = 0.25,
        execution: ExecutionSettings | None = None,
        planner: PickPlanner | None = None,
        observer: TrialObserver | None = None,
        obstacles: ObstacleSource = ObstacleSource.DEPTH,
        depth: DepthObstacleConfig | None = None,
    ) -> None:
        if not isinstance(obstacles, ObstacleSource):
            allowed = ", ".join(f"ObstacleSource.{s.name}" for s in ObstacleSource)
            raise InvalidInputError("obstacles", obstacles, f"one of {allowed}")
        self.task = task
        self.settle_s = settle_s
        self.execution = execution or ExecutionSettings()
        self.obstacle_source = obstacles
        self.world = World()
        self.depth = depth or yumi_depth_config(self.world.config)
        self.camera = HeadCamera()
        self.lighting = dataclasses.replace(self.camera.config.lighting,
                                            brightness=task.brightness)
        self.model: PerceptionModel = model(self.world, self.camera)
        self.planner = planner or make_yumi_planner()
        self.observer = observer
        if observer is not None:
            self.world.step_hook = observer.stepped

    def close(self) -> None:
        """Releases the simulator."""
        self.world.close()

    def __enter__(self) -> TrialRunner:
        return self

    def __exit__(self, *_: object) -> None:
        self.close()

    def setup(self, scene: Scene) -> list[int]:
        """Puts the robot at HOME and the scene's objects on the table; their body ids."""
        world = self.world
        world.reset_scene(yumi.HOME)
        bodies = [world.add_object(get_object_spec(o.object_type), o.position_xy_m, o.yaw_rad)
                  for o in scene.objects]
        world.step(round(self.settle_s / world.config.time_step_s))
        if isinstance(self.model, OraclePerception):  # distractors are never the oracle's targets
            self.model.candidates = tuple(b for b, o in zip(bodies, scene.objects, strict=True)
                                          if not o.distractor)
        return bodies

    def sense(self) -> RgbdFrame:
        """The head camera's RGB-D frame now, under the task's lighting, with its calibration."""
        return self.camera.render_rgbd(self.world.client, self.lighting)

    def render(self) -> np.ndarray:
        """The head camera's colour image now, under the task's lighting."""
        return self.sense().rgb

    def truth(self, body: int) -> Pose:
        """The canonical grasp of an object where it lies now (the referee's, never the robot's)."""
        return grasp_pose(self.world.object_spec(body), self.world.object_pose(body))

    def run(self, scene: Scene, index: int, seed: int, model_name: str) -> TrialRecord:
        """Runs one trial on ``scene``; every failure becomes a recorded outcome, never a crash."""
        started = time.perf_counter()
        base: dict[str, Any] = {"index": index, "seed": seed, "task": scene.task,
                                "model": model_name, "objects": scene.to_record()["objects"]}
        try:
            fields = self.pick_targets(scene, self.setup(scene))
        except (SimError, PerceptionError) as error:
            fields = {"outcome": TrialOutcome.PERCEPTION_FAILED, "reason": str(error)}
        except Exception as error:  # recorded, so a run is never lost to one bad trial
            last = traceback.extract_tb(error.__traceback__)[-1]
            fields = {"outcome": TrialOutcome.ERROR, "reason": f"{type(error).__name__}: "
                      f"{error} ({Path(last.filename).name}:{last.lineno})"}
        return TrialRecord(**base, **fields, sim_time_s=self.world.time_s,
                           wall_time_s=time.perf_counter() - started)

    def pick_targets(self, scene: Scene, bodies: list[int]) -> dict[str, Any]:
        """Picks every target of ``scene`` in order; the fields of the trial's record."""
        targets = [bodies[i] for i in scene.targets]
        picks: list[dict[str, Any]] = []
        for number, body in enumerate(targets):
            report = self.pick(scene, number, len(targets), body)
            picks.append(report.fields)
            if report.outcome is not TrialOutcome.SUCCESS:
                break
            if number + 1 < len(targets) and report.plan is not None:
                self._set_aside(body, report.plan)
        last = picks[-1]
        fields = {k: v for k, v in last.items() if k != "outcome"}
        fields["picks"] = [p | {"outcome": p["outcome"].value} for p in picks]
        done = sum(p["outcome"] is TrialOutcome.SUCCESS for p in picks)
        if done == len(targets):
            if len(targets) > 1:
                fields["reason"] = f"picked all {len(targets)} targets"
            return fields | {"outcome": TrialOutcome.SUCCESS}
        if len(targets) > 1:
            fields["reason"] = f"pick {len(picks)} of {len(targets)} ({last['target']}): " \
                               f"{last['reason']}"
        return fields | {"outcome": last["outcome"]}

    def pick(self, scene: Scene, number: int, total: int, body: int) -> PickReport:
        """Pick ``number`` of ``total``: sense, predict, plan from that alone, run, judge.

        ``body`` is the task's target for this pick: the referee's to judge by, never the
        plan's to act on.
        """
        frame = self.sense()
        truth = self.truth(body)  # the referee's label of this image, kept from the plan phase
        prediction = self.model.predict(frame.rgb, scene.condition)
        if self.observer is not None:
            self.observer.saw(frame.rgb, prediction)
        planned = self.plan_pick(frame, prediction, number, total)
        fields = {"target": self.world.object_spec(body).name,
                  "truth": pose_json(truth.position, truth.rotation)} | planned.fields
        predicted = planned.fields.get("predicted")
        if predicted is not None:
            position, rotation = (np.array(predicted[k]) for k in ("position_m", "rotation"))
            fields |= {"position_error_m": float(np.linalg.norm(position - truth.position)),
                       "rotation_error_rad": rotation_error_rad(truth.rotation, rotation)}
        if planned.plan is None or planned.grip is None:
            return PickReport(fields | {"outcome": planned.outcome, "reason": planned.reason},
                              None)
        executed = execute_pick(self.world, planned.plan, body, planned.grip.opening_m,
                                self.execution)
        return PickReport(fields | {"outcome": executed.outcome, "reason": executed.reason,
                                    "lift_m": executed.lift_m}, planned.plan)

    def plan_pick(self, frame: RgbdFrame, prediction: Prediction, number: int, total: int
                  ) -> PlannedPick:
        """The plan phase: the grip, the obstacles and the plan, from what the robot senses.

        Reads the frame, the prediction, the robot's joint state and the table, nothing of the
        objects (unless the runner was made with ``ObstacleSource.TRUTH``, for debugging).
        """
        index = number - (total - len(prediction.targets))
        if not 0 <= index < len(prediction.targets):
            return PlannedPick({}, outcome=TrialOutcome.PERCEPTION_FAILED,
                               reason=f"{self.model.name} predicted {len(prediction.targets)} "
                               f"targets; pick {number + 1} of {total} needs one")
        predicted: Target = prediction.targets[index]
        if predicted.rotation is None:
            raise InvalidInputError("prediction rotation", None,
                                    "a grasp pose: pick trials need models with grasp labels")
        try:  # a float32 output is a rotation to ~1e-6; inverse kinematics wants it exact
            rotation = nearest_rotation("predicted rotation", predicted.rotation)
        except PerceptionError as error:
            return PlannedPick({}, outcome=TrialOutcome.PERCEPTION_FAILED, reason=str(error))
        fields: dict[str, Any] = {"predicted": pose_json(predicted.position_m, rotation)}
        try:
            grip = grip_of(predicted)
        except InvalidInputError as error:
            return PlannedPick(fields, outcome=TrialOutcome.PERCEPTION_FAILED, reason=str(error))
        fields["grip"] = grip.to_record()
        grasp, fields["raised_m"] = clear_of_table(
            Pose(np.asarray(predicted.position_m, dtype=float), rotation), grip.opening_m)
        obstacles, target_obstacles, fields["obstacles"] = self._obstacles(frame, grasp, grip)
        result = self.planner.plan(PickRequest(
            T_world_grasp=grasp.as_se3(),
            q_start=self.planner.robot.q_from_dict(self.world.robot.joint_positions()),
            obstacles=(table_obstacle(self.world), *obstacles),
            target_obstacles=target_obstacles,
            alternatives=tuple(p.as_se3() for p in grip.alternatives(grasp)),
            finger_opening_m=grip.opening_m / 2,
            pregrasp_distance_m=grip.pregrasp_distance_m,
        ))
        fields["plan_status"] = result.status.value
        if result.plan is None:
            return PlannedPick(fields, grip, outcome=_PLAN_OUTCOMES[result.status],
                               reason=result.reason)
        return PlannedPick(fields | {"arm": result.plan.arm}, grip, result.plan)

    def _obstacles(self, frame: RgbdFrame, grasp: Pose, grip: Grip
                   ) -> tuple[tuple[AnyObstacle, ...], tuple[AnyObstacle, ...], dict[str, Any]]:
        """Obstacles and the target's own, and what the record keeps of them."""
        if self.obstacle_source is ObstacleSource.DEPTH:
            seen = depth_obstacles(frame.points_world(), np.asarray(frame.camera.position_m),
                                   self.depth, GraspRegion(grasp.as_se3(), grip.opening_m))
            return seen.obstacles, seen.target_obstacles, {"source": "depth"} | seen.to_record()
        world = self.world  # ObstacleSource.TRUTH: the debugging aid reads the true shapes
        aimed = nearest_object(world, grasp.position)
        others = object_obstacles(world, [b for b in world.objects if b != aimed])
        own = object_obstacles(world, [aimed]) if aimed is not None else []
        return tuple(others), tuple(own), {"source": "truth", "shapes": len(others) + len(own)}

    def _set_aside(self, body: int, plan: PickPlan) -> None:
        """Takes a picked object off the table, opens the hand and returns the arm to its start."""
        world = self.world
        world.remove_object(body)
        world.robot.open_gripper(plan.arm)
        retreat = plan.segment("retreat").trajectory
        world.robot.track(yumi.ARM_JOINTS[plan.arm], retreat.positions, retreat.velocities)
        world.robot.close_gripper(plan.arm)
        world.step(round(0.25 / world.config.time_step_s))
