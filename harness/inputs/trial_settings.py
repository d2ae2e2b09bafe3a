"""What a run of trials is (:class:`TrialSettings`, the fields of ``run.json``) and its model.

The model is named by ``TrialSettings.model`` as :mod:`sim.trials.trial_models` reads a name
(the oracle, a checkpoint folder, a plug-in's class, a served model); :func:`load_trial_model`
builds it and checks it against the task before the first trial. :mod:`harness.run_loop` runs
the trials.
"""

from __future__ import annotations

import sys
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from perception.learning.validation import HeldOutCheck, read_check
from perception.remote.client import RemoteModel, announced_metadata
from robots import DEFAULT_ROBOT, robot_identity, unnamed_robot
from robots.description import RobotDescription
from sim.errors import InvalidInputError
from sim.tasks.scene_specs import YUMI_SCENE
from sim.tasks.task_in_scene import check_task_fits, condition_choices
from sim.tasks.task_sensor import seen_through
from sim.tasks.task_spec import SIDES, TaskSpec, spaced_for
from sim.tasks.task_toml import TASK_FILES, with_test_phrases
from sim.tasks.variants import load_task_variant, variant_file
from sim.trials.closed_loop.loop_settings import Loop, LoopSettings
from sim.trials.execution import ExecutionSettings
from sim.trials.planner_setup import ObstacleSource, depth_config
from sim.trials.trial_models import (
    TRIAL_MODELS,
    ModelSource,
    TrialModel,
    checked_model,
    checkpoint_sensor,
    model_source,
)
from sim.world.head_camera import CameraConfig, camera_config
from sim.world.robot_choice import resolve_robot
from sim.world.sensor import SensorKind
from sim.world.world_config import check_wait_s


def task_identity(task: TaskSpec) -> dict[str, Any]:
    """A task's settings as JSON-able data (a resumed run must use the same task).

    :meth:`TaskSpec.recorded_fields`, its phrasings and enums as JSON: run folders from before
    sensors and per-scene distractors keep their identity.
    """
    data = task.recorded_fields()
    data["phrasings"] = None if task.phrasings is None else task.phrasings.to_json()
    for key, value in data.items():
        if hasattr(value, "value"):
            data[key] = value.value
    return data


def obstacle_identity(source: ObstacleSource) -> dict[str, Any]:
    """What a run's picks are planned around, as ``run.json`` and ``summary.json`` show it.

    Its depth settings are the unnamed robot's (the YuMi's) whatever robot picks, as
    identities have always held them (:func:`robots.unnamed_robot`).
    """
    if source is not ObstacleSource.DEPTH:
        return {"source": source.value}
    depth = asdict(depth_config(unnamed_robot()))
    depth["occluded"] = depth["occluded"].value
    return {"source": source.value, "depth": depth}


@dataclass(frozen=True)
class TrialSettings:
    """What a run of trials does; the fields of ``run.json``.

    Args:
        model: ``"oracle"`` or ``"oracle-view"`` (:data:`TRIAL_MODELS`), a checkpoint folder,
            a model that builds with no arguments (``"package.module:Class"`` or an installed
            plug-in's name), or ``"ws://HOST:PORT"``: a model ``gva serve`` serves elsewhere.
        task: A built-in task name, or the path of a task TOML file.
        n: Number of trials.
        seed: Seed of the test scenes.
        settle_s: Time objects settle on the table before the image is taken [s].
        execution: How picks are executed and judged.
        model_class: For a checkpoint folder only: ``"package.module:Class"`` that loads it
            (needed when its model is not registered); None: the model its config names.
        obstacles: What picks are planned around besides the table: the head camera's depth
            image (the default), or ``ObstacleSource.TRUTH``, the simulator's true shapes, to
            debug the planner (never for results: no real robot knows them).
        phrases: A phrase file (lines ``phrase<TAB>target``) that replaces a text task's test
            phrasings; None: the task's own.
        allow_sensor_change: Run a checkpoint under another sensor than the one its datasets
            were rendered by (``gva trials --allow-sensor-change``); refused otherwise.
        sensor: What the head camera renders through (``--sensor``), replacing the task
            file's ``[camera] sensor``; None: the file's, else a checkpoint's own (the sensor
            its datasets were rendered by:
            :func:`~sim.trials.model_fit.trained_sensor`), else the D435
            (:mod:`sim.tasks.task_sensor`).
        loop: Whether picks re-predict while the arm approaches (``--loop closed``,
            ``--replan-hz``; :mod:`sim.trials.closed_loop.loop`); open by default.
        robot: The robot that picks, one of :data:`robots.ROBOT_NAMES` (``--robot``), seen
            through its workcell's camera; the YuMi by default.
        variant: The task under a variant of its appearance (``--variant``: a built-in name or
            a variant file, :mod:`sim.tasks.variants`); None: the task as its file says.
        announced: For ``ws://`` only: what its server announced when the run began (``gva
            reproduce real`` asks once, then hands it to its jobs), so a job neither asks again
            nor fails when the server is down: its trials do, as ``perception_failed``. None:
            asked of the server (:func:`~perception.remote.client.announced_metadata`).

    """

    model: str
    task: str
    n: int = 30
    seed: int = 0
    settle_s: float = 0.25
    execution: ExecutionSettings = field(default_factory=ExecutionSettings)
    model_class: str | None = None
    obstacles: ObstacleSource = ObstacleSource.DEPTH
    phrases: str | None = None
    allow_sensor_change: bool = False
    loop: LoopSettings = field(default_factory=LoopSettings)
    robot: str = DEFAULT_ROBOT
    variant: str | None = None
    sensor: SensorKind | None = None
    announced: Mapping[str, Any] | None = field(default=None, hash=False)

    def __post_init__(self) -> None:
        self.description()  # an unknown robot is refused, naming those allowed
        if not isinstance(self.obstacles, ObstacleSource):
            allowed = ", ".join(repr(s.value) for s in ObstacleSource)
            raise InvalidInputError("obstacles", self.obstacles, f"one of {allowed}")
        source = model_source(self.model)
        if self.model_class is not None and source is not ModelSource.CHECKPOINT:
            raise InvalidInputError("model_class", self.model_class, "None unless model is a "
                                    "checkpoint folder (it names the class that loads it)")
        if self.announced is not None and source is not ModelSource.REMOTE:
            raise InvalidInputError("announced", "a server's metadata", "None unless model is "
                                    "ws://HOST:PORT (what its server announced)")
        if not (self.sensor is None or isinstance(self.sensor, SensorKind)):
            raise InvalidInputError("sensor", self.sensor, "None or one of " + ", ".join(
                f"SensorKind.{k.name}" for k in SensorKind))
        check_task_fits(self.task_spec, YUMI_SCENE)  # also: an unknown task names the allowed
        check_wait_s("settle_s", self.settle_s)
        if self.n < 1:
            raise InvalidInputError("n", self.n, "an integer >= 1")
        if self.seed < 0:
            raise InvalidInputError("seed", self.seed, "an integer >= 0")

    @property
    def task_spec(self) -> TaskSpec:
        """The task, read from its name or file, seen through its sensor, spaced for the hand.

        Its sensor is ``sensor``, else the file's, else the checkpoint's own, else the D435
        (:func:`~sim.tasks.task_sensor.seen_through`); its test phrasings come from
        ``phrases``, if set; its objects keep the distance the robot's hand needs
        (:func:`~sim.tasks.task_spec.spaced_for`).
        """
        task = seen_through(load_task_variant(self.task, self.variant), self.sensor,
                            checkpoint_sensor(self.model, self.announced))
        task = spaced_for(task, self.description().neighbour_spacing_m)
        if self.phrases is None:
            return task
        return with_test_phrases(task, self.phrases, condition_choices(task, YUMI_SCENE),
                                 YUMI_SCENE.object_types + SIDES)

    def identity(self) -> dict[str, Any]:
        """What identifies a run: a folder is only resumed by a run with the same identity.

        An open loop adds nothing, nor does the YuMi: folders from before closed loops and
        before other robots resume.
        """
        return {"model": self.model, "task": task_identity(self.task_spec), "seed": self.seed,
                "scene": YUMI_SCENE.name, "camera": asdict(self.camera_config()),
                "settle_s": self.settle_s, "execution": asdict(self.execution),
                "obstacles": obstacle_identity(self.obstacles)} | self._model_identity() | (
                    {} if self.loop.loop is Loop.OPEN else {"loop": self.loop.to_json()}) | (
                    robot_identity(self.robot))

    def description(self) -> RobotDescription:
        """The robot that picks."""
        return resolve_robot(self.robot)

    def camera_config(self) -> CameraConfig:
        """The camera the trials see through: the robot's workcell's."""
        return camera_config(self.description())

    def inputs(self) -> dict[str, Path | None]:
        """The files the run reads, for its provenance: the task file and the checkpoint's."""
        given = Path(self.task)
        files: dict[str, Path | None] = {
            "task_file": given if given.is_file() else TASK_FILES / f"{self.task}.toml"}
        if self.phrases is not None:
            files["phrases_file"] = Path(self.phrases)
        if self.variant is not None:
            files["variant_file"] = variant_file(self.variant)
        if model_source(self.model) is ModelSource.CHECKPOINT:
            from perception.learning.checkpoint import CONFIG_FILE, WEIGHTS_FILE

            files |= {"checkpoint_weights": Path(self.model) / WEIGHTS_FILE,
                      "checkpoint_config": Path(self.model) / CONFIG_FILE}
        return files

    def served_metadata(self) -> Mapping[str, Any]:
        """What a ``ws://`` model's server announced: ``announced``, else asked once."""
        if self.announced is not None:
            return self.announced
        return announced_metadata(self.model)

    def _model_identity(self) -> dict[str, Any]:
        """A checkpoint by its SHA-256s, not its path: other weights or values, another run.

        A run folder moved or copied with its checkpoint (or run from another directory)
        resumes; the same folder holding other weights does not. A served model by what its
        server announces (name, class, weights or source hash): another model behind the same
        address is another run.
        """
        source = model_source(self.model)
        if source is ModelSource.REMOTE:
            return {"announced": dict(self.served_metadata())}
        if source is not ModelSource.CHECKPOINT:
            return {}
        from perception.learning.checkpoint import read_config

        config = read_config(self.model)
        checksums = {key: config[key] for key in ("weights_sha256", "config_sha256")
                     if key in config}  # a version-1 checkpoint has no config_sha256
        return {"model": "checkpoint", "model_class": self.model_class} | checksums


def load_trial_model(settings: TrialSettings) -> TrialModel:
    """The model ``settings.model`` names, built, loaded and checked against the task.

    Raises:
        InvalidInputError: The model cannot be found or built, reads what a trial does not
            give, does not predict grasp poses, or was trained for another task; one line
            that says which.
        perception.learning.checkpoint.CheckpointError: The checkpoint cannot be used.

    """
    source = model_source(settings.model)
    if source is ModelSource.BUILT_IN:
        return TrialModel(TRIAL_MODELS[settings.model], settings.model, one_torch_thread=False)
    model = checked_model(settings.model, settings.task_spec, settings.description(),
                          settings.model_class, settings.allow_sensor_change, settings.announced)
    if isinstance(model, RemoteModel):
        label = f"{model.announced.get('name')} @ {settings.model}"
    elif source is ModelSource.CHECKPOINT:
        label = f"{model.name} {Path(settings.model).resolve().name}"
    else:
        label = model.name
    return TrialModel(lambda world, camera: model, label, one_torch_thread="torch" in sys.modules)


def held_out_check(settings: TrialSettings) -> HeldOutCheck | None:
    """The trials' checkpoint's held-out check (:mod:`perception.learning.validation`), if any."""
    if model_source(settings.model) is not ModelSource.CHECKPOINT:
        return None
    return read_check(settings.model)
