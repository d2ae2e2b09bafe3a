"""Collects a dataset: training scenes of a task, their images, conditions and labels.

``paper-sim``: each training scene is placed and rendered; the labels are the targets' true
positions. ``yumi``: each training scene is an expert demonstration: the oracle's grasps are
executed in the simulator, and the scene is kept only if every pick succeeded (a failed one is
redrawn from the next scene of the training stream, and counted). A demonstration keeps the
image the camera takes before each of its picks, as a trial sees them: a ``multiple`` scene
gives three samples, the second without the first target, the third with the last alone; a
sample's record lists the targets already taken under ``"taken"`` (their labels say where they
were; :meth:`perception.learning.data.Dataset.target_present` marks them absent). With
``approach_hz`` a demonstration also keeps images along each approach, the arm masked out of
them as in a closed-loop trial's re-predictions (the self filter), those in which the arm hides
at most :data:`APPROACH_HIDDEN_SHARE_MAX` of each target's footprint; a task
that moves its target during the pick is demonstrated by the oracle's closed loop, which follows
it (:mod:`sim.trials.closed_loop.loop`). Either way, scene
``i`` of a dataset comes from the training seed stream, never the test stream the trials use,
unless the settings ask for the test stream: a ``paper-sim`` test set (Table II scores models
on 100 test scenes) is collected like a training set, from ``SeedStream.TEST``. Scene ``i``
depends on the seed, the stream and ``i`` alone, so a dataset of 4 scenes is the first 4 of
one of 20.
"""

from __future__ import annotations

import enum
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from perception.labels import label_vector
from perception.learning.data import (
    JOINT_NAMES_KEY,
    Dataset,
    DatasetMetadata,
)
from perception.learning.dataset_file import save_dataset
from perception.learning.mirror import MIRROR_FLAG
from robots import DEFAULT_ROBOT, robot_identity
from robots.description import RobotDescription
from sim.errors import InvalidInputError, SimError
from sim.tasks.mirror_symmetry import mirror_symmetric
from sim.tasks.scene_sampling import RANDOMISED_LOOK_STREAM, Scene, SeedStream, sample_scene
from sim.tasks.scene_specs import SCENE_NAMES, SceneSpec, get_scene_spec
from sim.tasks.task_in_scene import check_task_fits, condition_choices
from sim.tasks.task_sensor import seen_in_scene
from sim.tasks.task_spec import TaskSpec, spaced_for
from sim.tasks.variants import load_task_variant
from sim.trials.closed_loop.loop_settings import Loop, LoopSettings
from sim.trials.pick_images import PickImages
from sim.trials.records import TrialOutcome
from sim.trials.scene_sets.catalog_labels import collect_catalog_scenes
from sim.trials.scene_sets.randomised_looks import RandomisedLooks, randomised
from sim.trials.scene_sets.samples import Sample, asked, scene_samples
from sim.trials.trial_runner import TrialRunner
from sim.world.head_camera import HeadCamera
from sim.world.robot_choice import resolve_robot
from sim.world.sensor import SensorKind

MAX_REDRAW_FACTOR = 3
"""A yumi collection gives up after this many times ``size`` failed demonstrations."""

APPROACH_HIDDEN_SHARE_MAX = 0.5
"""The most of a target's footprint (:func:`~sim.trials.closed_loop.view.hidden_share`) the arm
may hide in an approach image a demonstration keeps. A closed loop acts on the model's grasp
where the arm hides part of the target (the plain-view clause of
:func:`~sim.trials.closed_loop.view.unheeded_reason`), so the model learns there, labelled with
the truth; where the arm hides more, the label is one the image cannot show, and it would learn
to guess. 0 (issue 36's rule) taught no image of a
spray bottle with the hand near it, and `kqv` named it 1-4 cm off there (issue 66,
docs/decisions/closed-loop.md). Recorded in the dataset (``approach_hidden_share_max``)."""
HIDDEN_SHARE_KEY = "approach_hidden_share_max"
"""A dataset's note of the :data:`APPROACH_HIDDEN_SHARE_MAX` it was collected with; datasets from
before it (issue 36's rule) lack it: 0."""
APPROACH_MASKED_KEY = "approach_robot_masked"
"""A dataset's note that its approach images have the robot masked out (the self filter of
:meth:`~sim.world.head_camera.HeadCamera.render_rgbd`) and show at least half of every
target's footprint; datasets from before it lack it."""


class LabelSource(enum.Enum):
    """Where a ``yumi`` dataset's labels come from (``--labels``)."""

    PICKED = "picked"  # the oracle's grasps, each scene kept only if every pick succeeded
    CATALOG = "catalog"  # the catalog's grasp at each settled pose, never picked (scene_sets)


class LookSource(enum.Enum):
    """What a ``yumi`` dataset's scenes look like (``--looks``)."""

    TASK = "task"  # as the task (and its variant) says
    RANDOMISED = "randomised"  # wider than any variant, the held-out half never drawn


@dataclass(frozen=True)
class CollectSettings:
    """What to collect.

    Args:
        scene: ``paper-sim`` or ``yumi``.
        task: A built-in task name or the path of a task TOML file.
        size: Number of training scenes (the paper uses 4, 20 and 100); a ``yumi`` scene with
            several targets gives one sample per pick.
        seed: The seed the scenes are drawn from.
        stream: Which of the seed's streams: ``TRAIN`` (a training set) or ``TEST`` (a test
            set of untrained scenes); recorded as ``extra["stream"]`` in the metadata.
        every_condition: Whether a scene of a task with a condition gives one sample per
            condition value, each labelled with the object that value names (the same image;
            a yumi demonstration picks the drawn value's object, the others' labels are their
            grasps in that image). Then every Query learns from every scene and from the
            contrast between them, not from the third of the scenes its value was drawn for
            (``docs/decisions/every-condition.md``). None: for the training stream; a test
            set keeps the one drawn value per scene.
        approach_hz: ``yumi`` only: a demonstration also keeps an image every ``1 /
            approach_hz`` s of each approach, the arm masked out, labelled as the pick's image
            is, where the arm hides at most half of every target's footprint (the oracle's
            closed loop, :mod:`sim.trials.closed_loop.loop`; each such sample's record has
            ``"stage": "approach"``), so a model learns to predict while the arm moves. None (the
            default): the image before each pick only.
        robot: ``yumi`` scene only: the robot whose demonstrations these are, seen through its
            workcell's camera (one of :data:`robots.ROBOT_NAMES`; the YuMi by default). The
            metadata names it (``extra["robot"]``) where it is not the YuMi.
        variant: The task under a variant of its looks (``--variant``, :mod:`sim.tasks.variants`);
            None: the task as its file says. The dataset's task record holds the appearance.
        sensor: ``yumi`` scene only: what the head camera renders through (``--sensor``),
            replacing the task file's ``[camera] sensor``; None: the file's, else the D435
            (:mod:`sim.tasks.task_sensor`). The metadata's camera record names it. The
            ``paper-sim`` scene renders through its own ideal camera and takes none.
        labels: ``yumi`` scene only: ``PICKED`` (demonstrations, verified in physics) or
            ``CATALOG`` (each scene placed, settled and seen as a trial's, labelled with the
            oracle's grasps where its targets rest, never picked:
            :mod:`sim.trials.scene_sets.catalog_labels`); recorded as ``extra["labels"]``
            where it is not ``PICKED``.
        looks: ``yumi`` scene only: ``TASK`` or ``RANDOMISED`` (:class:`RandomisedLooks`:
            any colour per part, the train half's patterns, any table and lamp, look-alikes
            in some scenes; the task named ``<task>+randomised``); recorded as
            ``extra["looks"]`` where it is not ``TASK``. Not with a ``variant``: the
            randomised looks replace the task's.

    """

    scene: str
    task: str
    size: int
    seed: int = 0
    stream: SeedStream = SeedStream.TRAIN
    every_condition: bool | None = None
    approach_hz: float | None = None
    robot: str = DEFAULT_ROBOT
    variant: str | None = None
    sensor: SensorKind | None = None
    labels: LabelSource = LabelSource.PICKED
    looks: LookSource = LookSource.TASK

    def __post_init__(self) -> None:
        self.description()  # an unknown robot is refused, naming those allowed
        if self.robot != DEFAULT_ROBOT and self.scene != "yumi":
            raise InvalidInputError("robot", self.robot, f"{DEFAULT_ROBOT!r} for the "
                                    f"{self.scene} scene (it has no robot); another robot only "
                                    "in the yumi scene")
        if self.scene not in SCENE_NAMES:
            raise InvalidInputError("scene", self.scene, f"one of {', '.join(SCENE_NAMES)}")
        if not (self.sensor is None or isinstance(self.sensor, SensorKind)):
            raise InvalidInputError("sensor", self.sensor, "None or one of " + ", ".join(
                f"SensorKind.{k.name}" for k in SensorKind))
        for name, kind, default in (("labels", LabelSource, LabelSource.PICKED),
                                    ("looks", LookSource, LookSource.TASK)):
            value = getattr(self, name)
            if not isinstance(value, kind):
                allowed = ", ".join(f"{kind.__name__}.{k.name}" for k in kind)
                raise InvalidInputError(name, value, f"one of {allowed}")
            if value is not default and self.scene != "yumi":
                raise InvalidInputError(name, value.value, f"{default.value!r} for the "
                                        f"{self.scene} scene (its own labels and looks)")
        if self.looks is LookSource.RANDOMISED and self.variant is not None:
            raise InvalidInputError("looks", self.looks.value, "'task' with a variant (the "
                                    f"randomised looks would replace {self.variant!r}'s)")
        if self.labels is LabelSource.CATALOG and self.approach_hz is not None:
            raise InvalidInputError("approach_hz", self.approach_hz, "None with catalog labels "
                                    "(no pick: no approach to image)")
        check_task_fits(self.task_spec, get_scene_spec(self.scene))
        if self.size < 1:
            raise InvalidInputError("size", self.size, "an integer >= 1")
        if self.seed < 0:
            raise InvalidInputError("seed", self.seed, "an integer >= 0")
        if not isinstance(self.stream, SeedStream):
            allowed = ", ".join(f"SeedStream.{s.name}" for s in SeedStream)
            raise InvalidInputError("stream", self.stream, f"one of {allowed}")
        if self.every_condition not in (None, True, False):
            raise InvalidInputError("every_condition", self.every_condition,
                                    "None, True or False")
        if self.approach_hz is not None:
            if self.scene != "yumi":
                raise InvalidInputError("approach_hz", self.approach_hz, "None for the "
                                        f"{self.scene} scene (it has no robot to approach)")
            LoopSettings(Loop.CLOSED, self.approach_hz)  # the rate's bounds

    @property
    def task_spec(self) -> TaskSpec:
        """The task seen through the scene's sensor, its objects spaced for the robot's hand.

        :func:`~sim.tasks.task_sensor.seen_in_scene`, then :func:`spaced_for`; with randomised
        looks, :meth:`RandomisedLooks.with_look_alikes`.
        """
        task = spaced_for(seen_in_scene(load_task_variant(self.task, self.variant), self.scene,
                                        self.sensor), self.description().neighbour_spacing_m)
        return RandomisedLooks().with_look_alikes(task) \
            if self.looks is LookSource.RANDOMISED else task

    def scene_at(self, task: TaskSpec, spec: SceneSpec, index: int) -> Scene:
        """Scene ``index`` of the settings' seed and stream, in its randomised look if asked."""
        scene = sample_scene(task, spec, self.seed, self.stream, index)
        return randomised(scene, RandomisedLooks()) \
            if self.looks is LookSource.RANDOMISED else scene

    def recorded(self) -> dict[str, Any]:
        """What the metadata's ``extra`` says of the labels and looks, where not the defaults."""
        return ({} if self.labels is LabelSource.PICKED else {"labels": self.labels.value}) | (
            {} if self.looks is LookSource.TASK else {"looks": {
                "kind": self.looks.value, "look_stream": RANDOMISED_LOOK_STREAM,
                "draw": RandomisedLooks().to_json()}})

    def description(self) -> RobotDescription:
        """The robot that collects: ``robot`` resolved (the one place a collection does)."""
        return resolve_robot(self.robot)

    @property
    def asks_every_condition(self) -> bool:
        """Whether each scene gives a sample per condition value (see ``every_condition``)."""
        if self.every_condition is None:
            return self.stream is SeedStream.TRAIN
        return self.every_condition


def collect(settings: CollectSettings, out_path: str | Path, progress: bool = True) -> Dataset:
    """Collects the dataset ``settings`` describes and writes it to ``out_path``."""
    task, spec = settings.task_spec, get_scene_spec(settings.scene)
    # Every scene is drawn first (a millisecond each): a task that random placement cannot
    # fill is refused, naming its packing, before a world is built. (A yumi collection redraws
    # failed demonstrations from later scenes: those are drawn when needed.)
    for index in range(settings.size):
        settings.scene_at(task, spec, index)
    bar = tqdm(total=settings.size, disable=not progress, unit="scene",
               desc=f"collect {spec.name} / {task.name}")
    with bar:
        if spec.name == "paper-sim":
            samples, camera, extra = _collect_paper(task, spec, settings, bar)
        elif settings.labels is LabelSource.CATALOG:
            samples, camera, extra = collect_catalog_scenes(
                task, spec, lambda index: settings.scene_at(task, spec, index), settings.size,
                settings.asks_every_condition, settings.description(), bar)
            extra |= {"stream": settings.stream.name.lower(), "scenes": settings.size,
                      "every_condition": settings.asks_every_condition}
        else:
            samples, camera, extra = _collect_yumi(task, spec, settings, bar)
    first = samples[0]
    metadata = DatasetMetadata(
        scene=spec.name, task=task.name, size=len(samples), seed=settings.seed,
        image_height_px=first.image.shape[0], image_width_px=first.image.shape[1],
        label_kind=spec.label_kind, targets=first.labels.shape[0],
        condition_kind=task.model_condition, condition_choices=condition_choices(task, spec),
        camera=camera,
        extra=extra | {"task": _task_json(task), "object_types": list(spec.object_types)} | (
            robot_identity(settings.robot)) | settings.recorded(),
    )
    def stacked(name: str) -> np.ndarray | None:  # None where the scene gives none
        arrays = [getattr(s, name) for s in samples]
        return None if arrays[0] is None else np.stack(arrays).astype(np.float32)

    dataset = Dataset(metadata, np.stack([s.image for s in samples]),
                      np.stack([s.condition for s in samples]).astype(np.float32),
                      np.stack([s.labels for s in samples]).astype(np.float32),
                      tuple(s.scene for s in samples), depths_m=stacked("depth_m"),
                      joint_positions=stacked("joint_positions"))
    save_dataset(dataset, out_path)
    return dataset


def _task_json(task: TaskSpec) -> dict[str, Any]:
    """The task as a dataset's ``extra["task"]`` keeps it (the ideal sensor by omission).

    As :func:`~harness.inputs.trial_settings.task_identity` does, so a stored dataset is matched.
    """
    return json.loads(json.dumps(task.recorded_fields(), default=lambda v: v.value))


def _camera_json(camera: HeadCamera) -> dict[str, Any]:
    """The camera record: its config's fields and ``"sensor"``, the sensor it rendered through."""
    return camera.record()


def _collect_paper(
    task: TaskSpec, spec: SceneSpec, settings: CollectSettings, bar: tqdm
) -> tuple[list[Sample], dict[str, Any], dict[str, Any]]:
    from sim.world.paper_world import PaperWorld

    samples: list[Sample] = []
    with PaperWorld() as world:
        for index in range(settings.size):
            scene = sample_scene(task, spec, settings.seed, settings.stream, index)
            world.reset_scene()
            bodies = [world.add_object(o.object_type, o.position_xy_m, o.yaw_rad)
                      for o in scene.objects]
            world.settle()
            image = world.render(task.brightness)
            for question in asked(task, scene, settings.asks_every_condition):
                labels = np.stack([label_vector(world.object_position_m(bodies[t]))
                                   for t in question.targets])
                samples.append(Sample(image, question.given.vector(), labels,
                                      question.to_record()))
            bar.update()
        camera = _camera_json(world.camera)
    return samples, camera, {"stream": settings.stream.name.lower(), "scenes": settings.size,
                             "every_condition": settings.asks_every_condition}


def _collect_yumi(
    task: TaskSpec, spec: SceneSpec, settings: CollectSettings, bar: tqdm
) -> tuple[list[Sample], dict[str, Any], dict[str, Any]]:
    samples: list[Sample] = []
    redrawn: list[dict[str, Any]] = []
    index = kept = 0
    # A target moved during the pick (a task's disturbance) is followed as the oracle does in
    # closed loop: it re-reads the truth; without approach_hz only the pick images are kept.
    loop = None if settings.approach_hz is None and task.disturbance is None else LoopSettings(
        Loop.CLOSED, settings.approach_hz or LoopSettings.replan_hz)
    with TrialRunner(task, loop=loop, robot=settings.description()) as runner:
        images = PickImages(runner, APPROACH_HIDDEN_SHARE_MAX)
        runner.observer = images
        while kept < settings.size:
            if len(redrawn) > MAX_REDRAW_FACTOR * settings.size:
                raise SimError(
                    f"collect yumi / {task.name}: {len(redrawn)} of {index} demonstrations "
                    f"failed (last: {redrawn[-1]['reason']}); the task may not be pickable"
                )
            scene = settings.scene_at(task, spec, index)
            index += 1
            bodies = runner.setup(scene)
            images.start([bodies[t] for t in scene.targets])
            demonstration = runner.pick_targets(scene, bodies)
            if demonstration.outcome is not TrialOutcome.SUCCESS:
                redrawn.append({"scene_index": scene.index, "reason": demonstration.reason})
                bar.set_postfix_str(f"{len(redrawn)} redrawn")
                continue
            samples += scene_samples(task, scene, bodies, images, settings.asks_every_condition,
                                     approach=settings.approach_hz is not None)
            kept += 1
            bar.update()
        camera = _camera_json(runner.mounted_camera)  # as mounted: a look may move it per scene
    extra = {"stream": settings.stream.name.lower(), "scenes": settings.size,
             "every_condition": settings.asks_every_condition,
             JOINT_NAMES_KEY: list(images.joint_names),
             "demonstrations_redrawn": len(redrawn), "redrawn": redrawn,
             MIRROR_FLAG: mirror_symmetric(task, spec, runner.mounted_camera.config)}
    if settings.approach_hz is not None:  # the arm masked out of them (self-filtered frames)
        extra |= {"approach_hz": settings.approach_hz, APPROACH_MASKED_KEY: True,
                  HIDDEN_SHARE_KEY: APPROACH_HIDDEN_SHARE_MAX,
                  "approach_images_hidden": images.hidden}
    return samples, camera, extra
