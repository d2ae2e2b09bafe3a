"""Closed-loop pick trials: reset an untrained scene, predict, plan, execute, judge, record.

Trial ``i`` of a run with seed ``s`` runs test scene ``i`` of seed ``s`` (see
:mod:`sim.scene`), so the same seed gives the same trials, and no trial runs on a scene a model
was trained on. Every finished trial is appended to ``trials.jsonl`` before the next one starts;
running the same command again resumes where an interrupted run stopped.
"""

from __future__ import annotations

import json
import time
import traceback
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
from tqdm import tqdm

from control.pick import PickRequest, PlanStatus
from control.planner import PickPlanner
from perception.interface import PerceptionError, PerceptionModel, Prediction
from robots import yumi
from sim.camera import HeadCamera
from sim.errors import InvalidInputError, SimError
from sim.execution import ExecutionSettings, execute_pick
from sim.objects import Pose, get_object_spec, grasp_pose
from sim.oracle import OraclePerception
from sim.planning import make_yumi_planner, nearest_object, object_obstacles, table_obstacle
from sim.records import TrialLog, TrialOutcome, TrialRecord, TrialSummary
from sim.scene import Scene, SeedStream, sample_scene
from sim.tasks import get_task
from sim.world import World

ModelFactory = Callable[[World, HeadCamera], PerceptionModel]

MODELS: dict[str, ModelFactory] = {"oracle": OraclePerception}
"""Perception models the trial runner can build by name."""

_PLAN_OUTCOMES = {
    PlanStatus.UNREACHABLE: TrialOutcome.IK_UNREACHABLE,
    PlanStatus.COLLISION: TrialOutcome.PLAN_COLLISION,
    PlanStatus.START_IN_COLLISION: TrialOutcome.PLAN_COLLISION,
}


@dataclass(frozen=True)
class TrialSettings:
    """What a run of trials does; the fields of ``run.json``.

    Args:
        model: Perception model name (see :data:`MODELS`).
        task: Task name (see :mod:`sim.tasks`).
        n: Number of trials.
        seed: Seed of the test scenes.
        settle_s: Time objects settle on the table before the image is taken [s].
        execution: How picks are executed and judged.

    """

    model: str
    task: str
    n: int = 30
    seed: int = 0
    settle_s: float = 0.25
    execution: ExecutionSettings = field(default_factory=ExecutionSettings)

    def __post_init__(self) -> None:
        if self.model not in MODELS:
            raise InvalidInputError("model", self.model, f"one of {', '.join(MODELS)}")
        get_task(self.task)  # raises for an unknown task, naming the allowed ones
        if self.n < 1:
            raise InvalidInputError("n", self.n, "an integer >= 1")
        if self.seed < 0:
            raise InvalidInputError("seed", self.seed, "an integer >= 0")

    def identity(self) -> dict[str, Any]:
        """What identifies a run: a folder is only resumed by a run with the same identity."""
        return {"model": self.model, "task": self.task, "seed": self.seed,
                "settle_s": self.settle_s, "execution": asdict(self.execution)}


def _pose_json(position: np.ndarray, rotation: np.ndarray | None) -> dict[str, Any]:
    data: dict[str, Any] = {"position_m": [round(float(v), 6) for v in position]}
    if rotation is not None:
        data["rotation"] = [[round(float(v), 6) for v in row] for row in rotation]
    return data


def _rotation_error_rad(truth: np.ndarray, predicted: np.ndarray) -> float:
    """Angle between two TCP orientations, counting the gripper's half-turn symmetry."""
    flip = np.diag([-1.0, -1.0, 1.0])
    return min(float(np.linalg.norm(pin.log3(truth.T @ predicted @ f))) for f in (np.eye(3), flip))


class TrialRunner:
    """One world, camera, model and planner, reused across the trials of a run."""

    def __init__(self, settings: TrialSettings, planner: PickPlanner | None = None) -> None:
        self.settings = settings
        self.task = get_task(settings.task)
        self.world = World()
        self.camera = HeadCamera()
        self.model = MODELS[settings.model](self.world, self.camera)
        self.planner = planner or make_yumi_planner()

    def close(self) -> None:
        """Releases the simulator."""
        self.world.close()

    def __enter__(self) -> TrialRunner:
        return self

    def __exit__(self, *_: object) -> None:
        self.close()

    def scene(self, index: int) -> Scene:
        """The untrained test scene of trial ``index``."""
        return sample_scene(self.task, self.settings.seed, SeedStream.TEST, index)

    def run(self, index: int) -> TrialRecord:
        """Runs trial ``index``; every failure becomes a recorded outcome, never a crash."""
        started = time.perf_counter()
        scene = self.scene(index)
        base: dict[str, Any] = {"index": index, "seed": self.settings.seed, "task": scene.task,
                "model": self.settings.model}
        try:
            fields = self._run(scene)
        except (SimError, PerceptionError) as error:
            fields = {"outcome": TrialOutcome.PERCEPTION_FAILED, "reason": str(error)}
        except Exception as error:  # recorded, so a run is never lost to one bad trial
            last = traceback.extract_tb(error.__traceback__)[-1]
            fields = {"outcome": TrialOutcome.ERROR, "reason": f"{type(error).__name__}: "
                      f"{error} ({Path(last.filename).name}:{last.lineno})"}
        fields.setdefault("objects", [
            {"type": o.object_type, "position_xy_m": list(o.position_xy_m), "yaw_rad": o.yaw_rad}
            for o in scene.objects
        ])
        return TrialRecord(**base, **fields, sim_time_s=self.world.time_s,
                           wall_time_s=time.perf_counter() - started)

    def _run(self, scene: Scene) -> dict[str, Any]:
        world = self.world
        world.reset_scene(yumi.HOME)
        bodies = [world.add_object(get_object_spec(o.object_type), o.position_xy_m, o.yaw_rad)
                  for o in scene.objects]
        world.step(round(self.settings.settle_s / world.config.time_step_s))
        target_body = bodies[scene.targets[0]]
        spec = world.object_spec(target_body)
        truth = grasp_pose(spec, world.object_pose(target_body))
        image = self.camera.render(world.client)
        prediction = self.model.predict(image, scene.condition)
        fields: dict[str, Any] = {"target": spec.name,
                                  "truth": _pose_json(truth.position, truth.rotation)}
        if not prediction.targets:
            return fields | {"outcome": TrialOutcome.PERCEPTION_FAILED,
                             "reason": f"{self.model.name} predicted no target"}
        return fields | self._pick(prediction, truth, target_body)

    def _pick(self, prediction: Prediction, truth: Pose, target_body: int) -> dict[str, Any]:
        world, predicted = self.world, prediction.targets[0]
        if predicted.rotation is None:
            raise InvalidInputError("prediction rotation", None,
                                    "a grasp pose: pick trials need models with grasp labels")
        fields: dict[str, Any] = {
            "predicted": _pose_json(predicted.position_m, predicted.rotation),
            "position_error_m": float(np.linalg.norm(predicted.position_m - truth.position)),
            "rotation_error_rad": _rotation_error_rad(truth.rotation, predicted.rotation),
        }
        # The planner avoids every object but the one the prediction points at.
        aimed = nearest_object(world, predicted.position_m)
        aimed_spec = world.object_spec(aimed) if aimed is not None else None
        opening = aimed_spec.grasp.opening_m if aimed_spec else 2 * yumi.FINGER_TRAVEL_M
        obstacles = [table_obstacle(world)]
        obstacles += object_obstacles(world, [b for b in world.objects if b != aimed])
        q_start = self.planner.robot.q_from_dict(world.robot.joint_positions())
        result = self.planner.plan(PickRequest(
            T_world_grasp=pin.SE3(np.asarray(predicted.rotation), np.asarray(predicted.position_m)),
            q_start=q_start,
            obstacles=tuple(obstacles),
            finger_opening_m=opening / 2,
            pregrasp_distance_m=aimed_spec.grasp.pregrasp_distance_m if aimed_spec else None,
        ))
        fields["plan_status"] = result.status.value
        if result.plan is None:
            return fields | {"outcome": _PLAN_OUTCOMES[result.status], "reason": result.reason}
        fields["arm"] = result.plan.arm
        executed = execute_pick(world, result.plan, target_body, opening,
                                self.settings.execution)
        return fields | {"outcome": executed.outcome, "reason": executed.reason,
                         "lift_m": executed.lift_m}


def run_trials(
    settings: TrialSettings, out_dir: str | Path, progress: bool = True
) -> TrialSummary:
    """Runs (or resumes) ``settings.n`` trials into ``out_dir``; writes ``summary.json``."""
    out = Path(out_dir)
    log = TrialLog(out, settings.identity())
    todo = [i for i in range(settings.n) if not log.done(i)]
    if todo:
        with TrialRunner(settings) as runner, tqdm(
            total=settings.n, initial=settings.n - len(todo), disable=not progress,
            desc=f"{settings.model} / {settings.task}", unit="trial",
        ) as bar:
            for index in todo:
                log.append(runner.run(index))
                summary = log.summary(settings.n)
                bar.set_postfix_str(f"{summary.successes}/{summary.n} ok")
                bar.update()
    summary = log.summary(settings.n)
    data = {"settings": settings.identity() | {"n": settings.n}} | summary.to_dict()
    temporary = out / "summary.json.tmp"
    temporary.write_text(json.dumps(data, indent=2, sort_keys=True) + "\n")
    temporary.replace(out / "summary.json")
    return summary
