"""One pick trial in the ``yumi`` scene: set up, then for each target: image, predict, plan, run.

For a task with several targets (``multiple``) the robot picks them one after another. Before
each pick it takes a fresh image and asks the model again; each picked object is set aside
(taken off the table) after its lift and hold, and the arm returns to its start. A trial
succeeds when every target was picked. A model may omit targets it has already seen picked:
its predictions are matched to the task's targets from the end (the oracle returns only the
objects still on the table; a learned model with one head per target returns all of them).
"""

from __future__ import annotations

import dataclasses
import time
import traceback
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import pinocchio as pin

from control.pick import PickRequest, PlanStatus
from control.planner import PickPlanner
from perception.interface import PerceptionError, PerceptionModel, Prediction, Target
from perception.labels import nearest_rotation
from robots import yumi
from sim.camera import HeadCamera
from sim.errors import InvalidInputError, SimError
from sim.execution import ExecutionSettings, execute_pick
from sim.grasps import grasp_pose, symmetric_alternatives
from sim.objects import Pose, clear_of_table, get_object_spec
from sim.oracle import OraclePerception
from sim.planning import make_yumi_planner, nearest_object, object_obstacles, table_obstacle
from sim.records import TrialOutcome, TrialRecord
from sim.scene import Scene
from sim.tasks import TaskSpec
from sim.world import World

_PLAN_OUTCOMES = {
    PlanStatus.UNREACHABLE: TrialOutcome.IK_UNREACHABLE,
    PlanStatus.COLLISION: TrialOutcome.PLAN_COLLISION,
    PlanStatus.START_IN_COLLISION: TrialOutcome.PLAN_COLLISION,
}


class TrialObserver(Protocol):
    """Watches trials as they run, e.g. to record them (:class:`sim.recording.TrialRecorder`).

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

    """

    def __init__(
        self,
        task: TaskSpec,
        model: Any = OraclePerception,
        settle_s: float = 0.25,
        execution: ExecutionSettings | None = None,
        planner: PickPlanner | None = None,
        observer: TrialObserver | None = None,
    ) -> None:
        self.task = task
        self.settle_s = settle_s
        self.execution = execution or ExecutionSettings()
        self.world = World()
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

    def render(self) -> np.ndarray:
        """The head camera's image now, under the task's lighting."""
        return self.camera.render(self.world.client, self.lighting)

    def truth(self, body: int) -> Pose:
        """The canonical grasp of an object where it lies now."""
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
            image = self.render()
            prediction = self.model.predict(image, scene.condition)
            if self.observer is not None:
                self.observer.saw(image, prediction)
            pick, plan = self._pick_one(prediction, number, len(targets), body)
            picks.append(pick)
            if pick["outcome"] is not TrialOutcome.SUCCESS:
                break
            if number + 1 < len(targets):
                self._set_aside(body, plan)
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

    def _pick_one(
        self, prediction: Prediction, number: int, total: int, body: int
    ) -> tuple[dict[str, Any], Any]:
        world = self.world
        spec = world.object_spec(body)
        truth = self.truth(body)
        fields: dict[str, Any] = {"target": spec.name,
                                  "truth": pose_json(truth.position, truth.rotation)}
        index = number - (total - len(prediction.targets))
        if not 0 <= index < len(prediction.targets):
            return fields | {"outcome": TrialOutcome.PERCEPTION_FAILED,
                             "reason": f"{self.model.name} predicted {len(prediction.targets)} "
                             f"targets; pick {number + 1} of {total} needs one"}, None
        predicted: Target = prediction.targets[index]
        if predicted.rotation is None:
            raise InvalidInputError("prediction rotation", None,
                                    "a grasp pose: pick trials need models with grasp labels")
        try:  # a float32 output is a rotation to ~1e-6; inverse kinematics wants it exact
            rotation = nearest_rotation("predicted rotation", predicted.rotation)
        except PerceptionError as error:
            return fields | {"outcome": TrialOutcome.PERCEPTION_FAILED, "reason": str(error)}, None
        fields |= {
            "predicted": pose_json(predicted.position_m, rotation),
            "position_error_m": float(np.linalg.norm(predicted.position_m - truth.position)),
            "rotation_error_rad": rotation_error_rad(truth.rotation, rotation),
        }
        # The planner avoids every object but the one the prediction points at.
        aimed = nearest_object(world, predicted.position_m)
        aimed_spec = world.object_spec(aimed) if aimed is not None else None
        opening = aimed_spec.grasp.opening_m if aimed_spec else 2 * yumi.FINGER_TRAVEL_M
        grasp, fields["raised_m"] = clear_of_table(
            Pose(np.asarray(predicted.position_m), rotation), opening)
        obstacles = [table_obstacle(world)]
        obstacles += object_obstacles(world, [b for b in world.objects if b != aimed])
        target_shapes = object_obstacles(world, [aimed]) if aimed is not None else []
        result = self.planner.plan(PickRequest(
            T_world_grasp=grasp.as_se3(),
            q_start=self.planner.robot.q_from_dict(world.robot.joint_positions()),
            obstacles=tuple(obstacles),
            target_obstacles=tuple(target_shapes),
            alternatives=tuple(p.as_se3() for p in symmetric_alternatives(aimed_spec, grasp))
            if aimed_spec else (),
            finger_opening_m=opening / 2,
            pregrasp_distance_m=aimed_spec.grasp.pregrasp_distance_m if aimed_spec else None,
        ))
        fields["plan_status"] = result.status.value
        if result.plan is None:
            return fields | {"outcome": _PLAN_OUTCOMES[result.status],
                             "reason": result.reason}, None
        fields["arm"] = result.plan.arm
        executed = execute_pick(world, result.plan, body, opening, self.execution)
        return fields | {"outcome": executed.outcome, "reason": executed.reason,
                         "lift_m": executed.lift_m}, result.plan

    def _set_aside(self, body: int, plan: Any) -> None:
        """Takes a picked object off the table, opens the hand and returns the arm to its start."""
        world = self.world
        world.remove_object(body)
        world.robot.open_gripper(plan.arm)
        retreat = plan.segment("retreat").trajectory
        world.robot.track(yumi.ARM_JOINTS[plan.arm], retreat.positions, retreat.velocities)
        world.robot.close_gripper(plan.arm)
        world.step(round(0.25 / world.config.time_step_s))
