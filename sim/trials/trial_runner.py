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
the outcome; neither is handed to the plan phase. Beside the physics, the grasp judge
(:mod:`perception.judge.grasp_judge`) predicts each pick from its error alone, and the record keeps
its verdict, so a run tells the misses its perception explains from the rest.
"""

from __future__ import annotations

import dataclasses
import time
import traceback
from pathlib import Path

import numpy as np
import pinocchio as pin

from control.depth_obstacles import DepthObstacleConfig, GraspRegion
from control.pick import PickPlan, PickRequest, PlanStatus
from control.planner import PickPlanner
from control.retarget import JointState
from perception.camera import RgbdFrame
from perception.checks import check_inputs, check_prediction
from perception.errors import InvalidPredictionError
from perception.interface import (
    LabelKind,
    PerceptionError,
    PerceptionModel,
    Prediction,
    Target,
)
from perception.judge.grasp_judge import judge_grasp, yaw_of
from perception.labels import nearest_rotation
from perception.objects.catalog import clear_of_table, get_object_spec
from perception.objects.grasps import grasp_pose
from perception.poses import Pose
from robots.description import RobotDescription
from sim.errors import InvalidInputError, SimError
from sim.tasks.disturbance import scene_disturbance
from sim.tasks.scene_sampling import Scene
from sim.tasks.task_spec import TaskSpec
from sim.trials.closed_loop.loop import ApproachLoop
from sim.trials.closed_loop.loop_settings import Loop, LoopSettings
from sim.trials.execution import ExecutionSettings, execute_pick
from sim.trials.oracle import OraclePerception
from sim.trials.pick_results import (
    PickAttempt,
    PlannedPick,
    Sighting,
    TrialResult,
    as_recorded,
    trial_result,
)
from sim.trials.planner_setup import (
    ObstacleSource,
    depth_config,
    make_planner,
    pick_obstacles,
    table_obstacle,
)
from sim.trials.records import TrialOutcome, TrialRecord
from sim.trials.runner_hooks import TRIAL_INPUTS, ModelFactory, TrialObserver
from sim.world.grip import grip_of
from sim.world.head_camera import HeadCamera, camera_config
from sim.world.looks import SceneLook, lighting_for, moved_camera
from sim.world.sensor import SensorSeed
from sim.world.world_config import check_wait_s
from sim.world.yumi_world import World

_PLAN_OUTCOMES = {
    PlanStatus.UNREACHABLE: TrialOutcome.IK_UNREACHABLE,
    PlanStatus.COLLISION: TrialOutcome.PLAN_COLLISION,
    PlanStatus.START_IN_COLLISION: TrialOutcome.PLAN_COLLISION,
    PlanStatus.RETARGET_FAILED: TrialOutcome.PLAN_COLLISION,  # a closed loop's re-plan only
}


class TrialRunner:
    """One world, camera, model and planner, reused across the trials of a run.

    Args:
        task: The task the scenes are drawn from, seen through its sensor
            (:attr:`~sim.tasks.task_spec.TaskSpec.sensor`: the D435 where it names none).
        model: Builds the perception model from the world and camera (e.g. the oracle).
        settle_s: Time objects settle on the table before the first image [s].
        execution: How picks are executed and judged.
        planner: The pick planner; the YuMi's when None.
        observer: Sees every prediction and every physics step; None (the default) costs
            nothing.
        obstacles: What picks are planned around besides the table: the depth image (the
            default), or the simulator's true shapes (for debugging the planner only).
        depth: How depth points become obstacles; the YuMi workcell's when None.
        loop: Whether picks re-predict while the arm approaches; open when None.
        robot: The robot that picks (resolved where the run starts), seen through its camera.

    """

    def __init__(
        self,
        task: TaskSpec,
        model: ModelFactory = OraclePerception,
        settle_s: float = 0.25,
        execution: ExecutionSettings | None = None,
        planner: PickPlanner | None = None,
        observer: TrialObserver | None = None,
        obstacles: ObstacleSource = ObstacleSource.DEPTH,
        depth: DepthObstacleConfig | None = None,
        loop: LoopSettings | None = None,
        *,
        robot: RobotDescription,
    ) -> None:
        if not isinstance(obstacles, ObstacleSource):
            allowed = ", ".join(f"ObstacleSource.{s.name}" for s in ObstacleSource)
            raise InvalidInputError("obstacles", obstacles, f"one of {allowed}")
        check_wait_s("settle_s", settle_s)
        self.task = task
        self.settle_s = settle_s
        self.execution = execution or ExecutionSettings()
        self.loop = loop or LoopSettings()
        self.obstacle_source = obstacles
        self.world = World(robot=robot)
        self.depth = depth or depth_config(self.world.description, self.world.config)
        self.mounted_camera = HeadCamera(camera_config(robot), sensor=task.sensor)
        self.camera = self.mounted_camera  # a scene's look may move its mount (setup)
        self.frame_seed = SensorSeed()  # the next frame's; setup names the scene, sight counts
        self.task_lighting = dataclasses.replace(self.camera.config.lighting,
                                                 brightness=task.brightness)
        self.lighting = self.task_lighting  # a scene's look may draw its own (setup)
        self.model: PerceptionModel = model(self.world, self.camera)
        check_inputs(self.model, TRIAL_INPUTS, getattr(self.model, "name", repr(self.model)))
        self.planner = planner or make_planner(self.world.description)
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
        """Puts the robot at home and the scene's objects on the table; their body ids.

        The physics starts afresh (:meth:`World.rebuild`): a trial's record depends only on
        its task, model, seed and index, never on the trials run before it in this process;
        the sensor's noise, on the scene's seed, stream and index and the pick (:meth:`sight`).
        """
        world = self.world
        self.frame_seed = SensorSeed(scene.seed, int(scene.stream), scene.index)
        world.rebuild()
        world.reset_scene()
        look = scene.look
        bodies = [world.add_object(get_object_spec(o.object_type), o.position_xy_m, o.yaw_rad,
                                   None if look is None else look.objects[i])
                  for i, o in enumerate(scene.objects)]
        self._look(look)
        world.step(round(self.settle_s / world.config.time_step_s))
        world.sleep_resting_objects()
        if isinstance(self.model, OraclePerception):  # distractors are never the oracle's targets
            self.model.candidates = tuple(b for b, o in zip(bodies, scene.objects, strict=True)
                                          if not o.distractor)
            self.model.named = scene.condition  # what a sentence or a picture stands for
            self.model.camera = self.camera
        return bodies

    def _look(self, look: SceneLook | None) -> None:
        """The scene's table, light and camera mount (its objects' looks are on the bodies)."""
        if look is not None:
            self.world.dress_table(look.table)
        self.lighting = lighting_for(self.task_lighting, None if look is None else look.light)
        mount = None if look is None else look.mount
        self.camera = self.mounted_camera if mount is None else HeadCamera(
            moved_camera(self.mounted_camera.config, mount), sensor=self.task.sensor)

    def sense(self, self_filter: bool = False) -> RgbdFrame:
        """The head camera's RGB-D frame now, under the task's lighting, with its calibration.

        ``self_filter``: no depth on the robot's own pixels (a frame taken with the arm in view,
        :meth:`HeadCamera.render_rgbd`); the first image of a pick has the arms at HOME.
        """
        return self.camera.render_rgbd(self.world.client, self.lighting, self.frame_seed,
                                       self.world.robot.body_id if self_filter else None)

    def render(self) -> np.ndarray:
        """The head camera's colour image now, under the task's lighting."""
        return self.sense().rgb

    def truth(self, body: int) -> Pose:
        """The canonical grasp of an object where it lies now (the referee's, never the robot's)."""
        return grasp_pose(self.world.object_spec(body), self.world.object_pose(body))

    def run(self, scene: Scene, index: int, seed: int, model_name: str) -> TrialRecord:
        """Runs one trial on ``scene``; every failure becomes a recorded outcome, never a crash."""
        started = time.perf_counter()
        try:
            result = self.pick_targets(scene, self.setup(scene))
        except (SimError, PerceptionError) as error:
            result = TrialResult(TrialOutcome.PERCEPTION_FAILED, str(error))
        except Exception as error:  # recorded, so a run is never lost to one bad trial
            last = traceback.extract_tb(error.__traceback__)[-1]
            result = TrialResult(TrialOutcome.ERROR, f"{type(error).__name__}: {error} "
                                 f"({Path(last.filename).name}:{last.lineno})")
        record = scene.to_record()
        return TrialRecord(index=index, seed=seed, task=scene.task, model=model_name,
                           objects=record["objects"], **result.record_fields(),
                           sim_time_s=self.world.time_s,
                           wall_time_s=time.perf_counter() - started, asked=record.get("query"),
                           look=record.get("look"))

    def pick_targets(self, scene: Scene, bodies: list[int]) -> TrialResult:
        """Picks every target of ``scene`` in order, until one fails; how the trial went."""
        targets = [bodies[i] for i in scene.targets]
        picks: list[PickAttempt] = []
        for number, body in enumerate(targets):
            attempt = self.pick(scene, number, len(targets), body)
            picks.append(attempt)
            if not self.next_pick(attempt, body, number, len(targets)):
                break
        return trial_result(picks, len(targets))

    def next_pick(self, attempt: PickAttempt, body: int, number: int, total: int) -> bool:
        """Whether another pick follows ``attempt``; if so, the picked object is set aside first."""
        if attempt.outcome is not TrialOutcome.SUCCESS or number + 1 >= total:
            return False
        if attempt.planned.plan is not None:
            self._set_aside(body, attempt.planned.plan)
        return True

    def sight(self, body: int, self_filter: bool = False) -> Sighting:
        """The head camera's frame now, and the referee's note of ``body``, the pick's target.

        Each sighting since :meth:`setup` is the next pick's: its frame's noise is seeded by it.
        """
        frame, seed = self.sense(self_filter), self.frame_seed
        self.frame_seed = dataclasses.replace(seed, frame=seed.frame + 1)
        return Sighting(frame, body, self.world.object_spec(body).name, self.truth(body),
                        yaw_of(self.world.object_pose(body).rotation))

    def pick(self, scene: Scene, number: int, total: int, body: int) -> PickAttempt:
        """Pick ``number`` of ``total``: sense, predict, plan from that alone, run, judge.

        ``body`` is the task's target for this pick: the referee's to judge by, never the
        plan's to act on.
        """
        sighting = self.sight(body)
        try:
            prediction = self.model.predict_frame(sighting.frame, scene.given)
        except Exception as error:  # the model's failure, recorded with its traceback
            if self.observer is not None:
                self.observer.saw(sighting.frame, None)
            failed = PlannedPick(TrialOutcome.PERCEPTION_FAILED, f"{self.model.name}'s predict "
                                 f"raised {type(error).__name__}: {error}",
                                 traceback=traceback.format_exc())
            return PickAttempt(sighting.target, sighting.truth, failed,
                               TrialOutcome.PERCEPTION_FAILED, failed.reason)
        return self.attempt(sighting, prediction, number, total, scene)

    def attempt(self, sighting: Sighting, prediction: Prediction, number: int, total: int,
                scene: Scene | None = None) -> PickAttempt:
        """Acts on ``prediction`` of the frame in ``sighting``: plan, run, judge.

        What a trial does with its model's prediction, and what the Gymnasium environment
        (:mod:`sim.envs`) does with an agent's grasp: one code path, so both get the same
        outcome for the same grasp. With ``scene``, the first pick's approach is run by an
        :class:`~sim.trials.closed_loop.loop.ApproachLoop` where the loop is closed or the task
        moves its target (:mod:`sim.trials.closed_loop.loop`).
        """
        planned = self.plan_pick(sighting.frame, prediction, number, total)
        if self.observer is not None:  # the Prediction once checked, else None
            self.observer.saw(sighting.frame, prediction if planned.predicted is not None else None)
        spec = self.world.object_spec(sighting.body)
        verdict = None if planned.predicted is None else judge_grasp(
            spec, sighting.truth, as_recorded(planned.predicted), sighting.object_yaw_rad)
        if planned.plan is None or planned.grip is None:
            assert planned.outcome is not None  # a plan phase that ends a pick says how
            return PickAttempt(sighting.target, sighting.truth, planned, planned.outcome,
                               planned.reason, verdict=verdict)
        follow = self._approach_loop(scene, number, total, sighting.body, planned)
        executed = execute_pick(self.world, planned.plan, sighting.body, planned.grip.opening_m,
                                self.execution, follow)
        if follow is not None:  # judged as run: the grasp followed, the target where it lay
            verdict = follow.judged(spec)
        return PickAttempt(sighting.target, sighting.truth, planned, executed.outcome,
                           executed.reason, executed.lift_m, verdict,
                           None if follow is None else follow.to_record())

    def _approach_loop(self, scene: Scene | None, number: int, total: int, body: int,
                       planned: PlannedPick) -> ApproachLoop | None:
        """The closed loop of this pick, or its disturbance's (the first pick's only)."""
        draw = None if scene is None or number else scene_disturbance(
            self.task.disturbance, scene.seed, scene.index, int(scene.stream))
        if scene is None or (self.loop.loop is Loop.OPEN and draw is None):
            return None
        return ApproachLoop(self, scene, number, total, body, planned, self.loop, draw)

    def read_grasp(self, prediction: Prediction, number: int, total: int) -> PlannedPick:
        """The grasp and grip ``prediction`` states for pick ``number`` of ``total``.

        A prediction the robot cannot act on (:func:`perception.checks.check_prediction`, a
        grip it cannot make) ends the pick as ``perception_failed`` (the outcome is set). A
        model may omit the targets already picked: its targets are matched from the end.
        """
        try:
            targets = check_prediction(prediction, self.model.name, least=total - number,
                                       most=total, label_kind=LabelKind.GRASP_POSE)
        except InvalidPredictionError as error:
            return PlannedPick(TrialOutcome.PERCEPTION_FAILED, str(error))
        predicted: Target = targets[number - (total - len(targets))]
        assert predicted.rotation is not None  # check_prediction: a grasp pose has one
        # a float32 output is a rotation to ~1e-6; inverse kinematics wants it exact
        rotation = nearest_rotation("predicted rotation", predicted.rotation)
        grasp = Pose(np.asarray(predicted.position_m, dtype=float), rotation)
        try:
            grip = grip_of(predicted, self.world.description.max_opening_m)
            return PlannedPick(None, "", grasp, grip)
        except InvalidInputError as error:
            return PlannedPick(TrialOutcome.PERCEPTION_FAILED, str(error), grasp)

    def plan_pick(self, frame: RgbdFrame, prediction: Prediction, number: int, total: int,
                  moving: JointState | None = None, remembered: np.ndarray | None = None,
                  ) -> PlannedPick:
        """The plan phase: the grip, the obstacles and the plan, from what the robot senses.

        Reads the frame, the prediction (:meth:`read_grasp`), the robot's joint state and the
        table, nothing of the objects (unless the runner was made with
        ``ObstacleSource.TRUTH``, for debugging). ``moving``: the arm is in motion (a closed
        loop's re-plan): the plan keeps to it and its approach starts from this state
        (:meth:`~control.planner.PickPlanner.replan`). ``remembered`` (M, 3): obstacle points
        an earlier frame saw where this one has no depth (the arm hides them).
        """
        read = self.read_grasp(prediction, number, total)
        if read.outcome is not None or read.predicted is None or read.grip is None:
            return read
        grasp, grip = read.predicted, read.grip
        raised, raised_m = max(  # clear for whichever of the robot's hands picks
            (clear_of_table(grasp, grip.opening_m, arm.gripper.fingers)
             for arm in self.world.description.arms), key=lambda lifted: lifted[1])
        obstacles = pick_obstacles(self.world, self.obstacle_source, self.depth, frame,
                                   GraspRegion(pin.SE3(raised.matrix), grip.opening_m), remembered)
        request = PickRequest(
            T_world_grasp=pin.SE3(raised.matrix),
            q_start=self.planner.robot.q_from_dict(self.world.robot.joint_positions()),
            obstacles=(table_obstacle(self.world), *obstacles.obstacles),
            target_obstacles=obstacles.target,
            alternatives=tuple(pin.SE3(p.matrix) for p in grip.alternatives(raised)),
            finger_opening_m=grip.opening_m / 2,
            pregrasp_distance_m=grip.pregrasp_distance_m,
        )
        result = (self.planner.plan(request) if moving is None
                  else self.planner.replan(request, moving))
        planned = PlannedPick(None, "", grasp, grip, raised_m, obstacles.record, result.status,
                              result.plan, obstacle_image=obstacles.image)
        if result.plan is None:
            return dataclasses.replace(planned, outcome=_PLAN_OUTCOMES[result.status],
                                       reason=result.reason)
        return planned

    def _set_aside(self, body: int, plan: PickPlan) -> None:
        """Takes a picked object off the table, opens the hand and returns the arm to its start."""
        world = self.world
        world.remove_object(body)
        world.robot.open_gripper(plan.arm)
        retreat = plan.segment("retreat").trajectory
        world.robot.track(world.description.arm(plan.arm).joints, retreat.positions,
                          retreat.velocities)
        world.robot.close_gripper(plan.arm)
        world.step(round(0.25 / world.config.time_step_s))
        world.sleep_resting_objects()  # what the pick brushed against has stopped again
