"""Runs of closed-loop pick trials: settings, the resumable loop, the summary.

Trial ``i`` of a run with seed ``s`` runs test scene ``i`` of seed ``s`` (see
:mod:`sim.tasks.scene_sampling`), so the same seed gives the same trials, and no trial runs on a
scene a model was trained on. Every finished trial is appended to ``trials.jsonl`` before the
next one starts; running the same command again resumes where an interrupted run stopped.

The model is named by ``TrialSettings.model``: ``"oracle"``; a checkpoint folder (``gva
train`` writes one), checked against the task before the first trial; or a model of your own
built with no arguments: ``"package.module:Class"`` or the name an installed package registers
(:mod:`perception.plugins`). A model that uses torch runs its inference on one torch thread: a
trial predicts one image at a time, where more threads cost more than they save, and runs of
trials side by side would fight for the cores.

A model that misbehaves costs its trial, never the run: each pick records it as
``perception_failed`` (:mod:`sim.trials.trial_runner`). Only ``KeyboardInterrupt`` (Ctrl-C) and
``SystemExit`` stop a run; :class:`RunStopped` then carries the summary of what finished, and
the same command resumes it.
"""

from __future__ import annotations

import contextlib
import enum
import json
import sys
from collections.abc import Iterator
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from tqdm import tqdm

from perception.checks import check_inputs
from perception.files import atomic_write
from perception.interface import LabelKind, PerceptionModel
from perception.learnable import LearnableModel, ModelSpec
from perception.plugins import build_plugin, installed_models, is_class_path, plugin_class
from perception.validation import HeldOutCheck, read_check
from sim.errors import InvalidInputError
from sim.jobs import JobPool
from sim.tasks.scene_sampling import (
    Scene,
    SeedStream,
    check_task_fits,
    condition_choices,
    sample_scene,
    target_count,
)
from sim.tasks.scene_specs import YUMI_SCENE
from sim.tasks.task_spec import TASK_FILES, TaskSpec, load_task
from sim.trials.execution import ExecutionSettings
from sim.trials.oracle import OraclePerception
from sim.trials.planner_setup import ObstacleSource, yumi_depth_config
from sim.trials.provenance import provenance
from sim.trials.records import TrialLog, TrialRecord, TrialSummary, run_folder_lock
from sim.trials.trial_runner import TRIAL_INPUTS, ModelFactory, TrialRunner
from sim.world.head_camera import CameraConfig
from sim.world.yumi_world import check_wait_s

MODELS: dict[str, ModelFactory] = {"oracle": OraclePerception}
"""Perception models the trial runner builds by name; a checkpoint folder or
``"package.module:Class"`` names any other (see :func:`load_trial_model`)."""

_ALLOWED_MODELS = (f"one of {', '.join(MODELS)}, a checkpoint folder (gva train writes one), "
                   "'package.module:Class' or the name an installed package registers in "
                   "'gva.models'")


class ModelSource(enum.Enum):
    """Where the model of a run of trials comes from."""

    BUILT_IN = "built_in"  # a name in MODELS
    CHECKPOINT = "checkpoint"  # a checkpoint folder of a learnable model
    CLASS = "class"  # "package.module:Class" or an installed plug-in's name: built with no
    # arguments


def model_source(model: str) -> ModelSource:
    """Where ``model`` (a name, a folder or ``"package.module:Class"``) comes from."""
    if not isinstance(model, str) or not model:
        raise InvalidInputError("model", model, _ALLOWED_MODELS)
    if model in MODELS:
        return ModelSource.BUILT_IN
    if Path(model).is_dir():
        return ModelSource.CHECKPOINT
    if is_class_path(model) or model in installed_models():
        return ModelSource.CLASS
    raise InvalidInputError("model", model, _ALLOWED_MODELS)


def task_identity(task: TaskSpec) -> dict[str, Any]:
    """A task's settings as JSON-able data (a resumed run must use the same task)."""
    data = asdict(task)
    data.pop("source")
    for key, value in data.items():
        if hasattr(value, "value"):
            data[key] = value.value
    return data


def obstacle_identity(source: ObstacleSource) -> dict[str, Any]:
    """What a run's picks are planned around, as ``run.json`` and ``summary.json`` show it."""
    if source is not ObstacleSource.DEPTH:
        return {"source": source.value}
    depth = asdict(yumi_depth_config())
    depth["occluded"] = depth["occluded"].value
    return {"source": source.value, "depth": depth}


@dataclass(frozen=True)
class TrialSettings:
    """What a run of trials does; the fields of ``run.json``.

    Args:
        model: ``"oracle"`` (see :data:`MODELS`), a checkpoint folder, or a model that builds
            with no arguments: ``"package.module:Class"`` or an installed plug-in's name.
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

    """

    model: str
    task: str
    n: int = 30
    seed: int = 0
    settle_s: float = 0.25
    execution: ExecutionSettings = field(default_factory=ExecutionSettings)
    model_class: str | None = None
    obstacles: ObstacleSource = ObstacleSource.DEPTH

    def __post_init__(self) -> None:
        if not isinstance(self.obstacles, ObstacleSource):
            allowed = ", ".join(repr(s.value) for s in ObstacleSource)
            raise InvalidInputError("obstacles", self.obstacles, f"one of {allowed}")
        source = model_source(self.model)
        if self.model_class is not None and source is not ModelSource.CHECKPOINT:
            raise InvalidInputError("model_class", self.model_class, "None unless model is a "
                                    "checkpoint folder (it names the class that loads it)")
        check_task_fits(self.task_spec, YUMI_SCENE)  # also: an unknown task names the allowed
        check_wait_s("settle_s", self.settle_s)
        if self.n < 1:
            raise InvalidInputError("n", self.n, "an integer >= 1")
        if self.seed < 0:
            raise InvalidInputError("seed", self.seed, "an integer >= 0")

    @property
    def task_spec(self) -> TaskSpec:
        """The task, read from its name or file."""
        return load_task(self.task)

    def identity(self) -> dict[str, Any]:
        """What identifies a run: a folder is only resumed by a run with the same identity."""
        return {"model": self.model, "task": task_identity(self.task_spec), "seed": self.seed,
                "scene": YUMI_SCENE.name, "camera": asdict(CameraConfig()),
                "settle_s": self.settle_s, "execution": asdict(self.execution),
                "obstacles": obstacle_identity(self.obstacles)} | self._model_identity()

    def inputs(self) -> dict[str, Path | None]:
        """The files the run reads, for its provenance: the task file and the checkpoint's."""
        given = Path(self.task)
        files: dict[str, Path | None] = {
            "task_file": given if given.is_file() else TASK_FILES / f"{self.task}.toml"}
        if model_source(self.model) is ModelSource.CHECKPOINT:
            from perception.checkpoint import CONFIG_FILE, WEIGHTS_FILE

            files |= {"checkpoint_weights": Path(self.model) / WEIGHTS_FILE,
                      "checkpoint_config": Path(self.model) / CONFIG_FILE}
        return files

    def _model_identity(self) -> dict[str, Any]:
        """A checkpoint by its SHA-256s, not its path: other weights or values, another run.

        A run folder moved or copied with its checkpoint (or run from another directory)
        resumes; the same folder holding other weights does not.
        """
        if model_source(self.model) is not ModelSource.CHECKPOINT:
            return {}
        from perception.checkpoint import read_config

        config = read_config(self.model)
        checksums = {key: config[key] for key in ("weights_sha256", "config_sha256")
                     if key in config}  # a version-1 checkpoint has no config_sha256
        return {"model": "checkpoint", "model_class": self.model_class} | checksums


@dataclass(frozen=True)
class TrialModel:
    """The perception model of a run, as :class:`TrialRunner` builds it.

    Args:
        factory: Builds the model from the runner's world and camera.
        label: A short name for progress bars.
        one_torch_thread: Limit torch to one thread during the trials (a model that uses
            torch: it was imported when the model was built).

    """

    factory: ModelFactory
    label: str
    one_torch_thread: bool


def load_trial_model(settings: TrialSettings) -> TrialModel:
    """The model ``settings.model`` names, built, loaded and checked against the task.

    Raises:
        InvalidInputError: The model cannot be found or built, reads what a trial does not
            give, does not predict grasp poses, or was trained for another task; one line
            that says which.
        perception.checkpoint.CheckpointError: The checkpoint cannot be used.

    """
    source = model_source(settings.model)
    if source is ModelSource.BUILT_IN:
        return TrialModel(MODELS[settings.model], settings.model, one_torch_thread=False)
    model: PerceptionModel
    if source is ModelSource.CHECKPOINT:
        from perception.registry import load_model  # imports torch: not for the oracle

        model = load_model(settings.model, settings.model_class)
        label = f"{model.name} {Path(settings.model).resolve().name}"
    else:
        if issubclass(plugin_class(settings.model), LearnableModel):
            raise InvalidInputError("model", settings.model, "a model without weights; a "
                                    "learnable one loads from its checkpoint folder: --model "
                                    f"FOLDER --model-class {settings.model}")
        model = build_plugin(settings.model)
        label = model.name
    check_inputs(model, TRIAL_INPUTS, settings.model)
    check_model_fits_task(model, settings.task_spec, settings.model)
    return TrialModel(lambda world, camera: model, label, one_torch_thread="torch" in sys.modules)


def check_model_fits_task(model: PerceptionModel, task: TaskSpec, where: str) -> None:
    """Raises unless ``model`` predicts grasp poses for what ``task`` asks in the yumi scene.

    A model with a :class:`~perception.learnable.ModelSpec` must have been trained on the yumi
    scene with the task's condition (kind and choices), target count and the head camera's
    image size. Its task may have another name (e.g. the same task under dimmer light).
    """
    kind = getattr(model, "label_kind", None)
    if kind is not LabelKind.GRASP_POSE:
        shown = kind.value if isinstance(kind, LabelKind) else kind
        raise InvalidInputError(f"model {where}: label_kind", shown, "'grasp_pose': pick trials "
                                "need a grasp pose (TCP position and rotation) per target; a "
                                "position model (e.g. one trained on paper-sim) cannot pick")
    if not isinstance(model, LearnableModel) or not isinstance(model.spec, ModelSpec):
        return
    spec = model.spec
    camera = CameraConfig()
    needed = (YUMI_SCENE.name, task.condition.value, condition_choices(task, YUMI_SCENE),
              target_count(task), camera.height_px, camera.width_px)
    trained = (spec.scene, spec.condition_kind.value, tuple(spec.condition_choices),
               spec.targets, spec.image_height_px, spec.image_width_px)
    if trained != needed:
        raise InvalidInputError(f"model {where}", f"trained for task {spec.task} "
                                f"{_describe(*trained)}", f"a checkpoint for trial task "
                                f"{task.name} {_describe(*needed)}")


def _describe(scene: str, condition: str, choices: tuple[str, ...], targets: int,
              height_px: int, width_px: int) -> str:
    over = f"{condition} condition over {', '.join(choices)}" if choices else "no condition"
    return (f"on scene {scene} ({over}; {targets} target{'s' * (targets != 1)}; "
            f"{width_px}x{height_px} px images)")


@contextlib.contextmanager
def torch_threads(threads: int) -> Iterator[None]:
    """Torch on ``threads`` CPU threads inside the block, as before after it."""
    import torch

    previous = torch.get_num_threads()
    torch.set_num_threads(threads)
    try:
        yield
    finally:
        torch.set_num_threads(previous)


def held_out_check(settings: TrialSettings) -> HeldOutCheck | None:
    """The held-out check of the trials' checkpoint (:mod:`perception.validation`), if any."""
    if model_source(settings.model) is not ModelSource.CHECKPOINT:
        return None
    return read_check(settings.model)


TRIAL_WORKERS = 1
"""Processes a run of trials uses by default: one (a trial is one image and one plan at a
time; ``--workers`` runs several side by side)."""


class RunStopped(BaseException):
    """A run stopped before its last trial by Ctrl-C or ``SystemExit``; what finished is kept.

    A ``BaseException``, as the two it stands for: no ``except Exception`` swallows it.

    Args:
        summary: The trials that finished, as ``summary.json`` holds them.
        cause: The ``KeyboardInterrupt`` or ``SystemExit`` that stopped the run.

    """

    def __init__(self, summary: TrialSummary, cause: BaseException) -> None:
        self.summary, self.cause = summary, cause
        why = "interrupted" if isinstance(cause, KeyboardInterrupt) else \
            f"the model raised SystemExit({getattr(cause, 'code', None)!r})"
        super().__init__(f"{why} after {summary.n} finished trials")


def run_trials(
    settings: TrialSettings, out_dir: str | Path, progress: bool = True,
    workers: int = TRIAL_WORKERS,
) -> TrialSummary:
    """Runs (or resumes) ``settings.n`` trials into ``out_dir``; writes ``summary.json``.

    The folder is locked for the run (:func:`~sim.trials.records.run_folder_lock`). With
    ``workers`` > 1 the trials run side by side in that many processes (:mod:`sim.jobs`), and
    this process appends each record as it comes: every trial starts from a rebuilt world, so
    the records are those of one process, in the order they finish.

    Raises:
        RunStopped: Ctrl-C or ``SystemExit`` stopped the run; ``summary.json`` holds what
            finished, and the same call resumes.
        RunFolderError: Another run holds the folder, or it holds a different run.

    """
    if not isinstance(workers, int) or isinstance(workers, bool) or workers < 1:
        raise InvalidInputError("workers", workers, "an integer >= 1")
    out = Path(out_dir)
    # Every scene is drawn first (a millisecond each): a task that random placement cannot fill
    # is refused, naming its packing, before a model loads, a run folder is made or a trial runs.
    for index in range(settings.n):
        _scene(settings, index)
    model = load_trial_model(settings)  # a refused model leaves no run folder behind
    with run_folder_lock(out):
        session = provenance(settings.inputs())
        log = TrialLog(out, settings.identity(), session)
        todo = [i for i in range(settings.n) if not log.done(i)]
        try:
            _run_todo(settings, model, log, todo, progress, workers)
        except (KeyboardInterrupt, SystemExit) as stop:
            raise RunStopped(_write_summary(settings, log, out, session), stop) from stop
        return _write_summary(settings, log, out, session)


def _run_todo(settings: TrialSettings, model: TrialModel, log: TrialLog, todo: list[int],
              progress: bool, workers: int) -> None:
    """Runs the trials ``todo``, appending each to ``log`` as it finishes."""
    if not todo:
        return
    task = settings.task_spec
    with tqdm(total=settings.n, initial=settings.n - len(todo), disable=not progress,
              desc=f"{model.label} / {task.name}", unit="trial") as bar:
        def done(record: TrialRecord) -> None:
            log.append(record)
            summary = log.summary(settings.n)
            bar.set_postfix_str(f"{summary.successes}/{summary.n} ok")
            bar.update()

        if workers > 1 and len(todo) > 1:
            with JobPool(min(workers, len(todo))) as pool:
                pool.run(run_trial_job, [TrialJob(settings, i) for i in todo], done)
            return
        threads = torch_threads(1) if model.one_torch_thread else contextlib.nullcontext()
        with threads, TrialRunner(task, model.factory, settings.settle_s, settings.execution,
                                  obstacles=settings.obstacles) as runner:
            for index in todo:
                done(runner.run(_scene(settings, index), index, settings.seed, settings.model))


@dataclass(frozen=True)
class TrialJob:
    """One trial of a run, as a worker process runs it."""

    settings: TrialSettings
    index: int


_WORKER_RUNNER: list[tuple[TrialSettings, TrialRunner]] = []
"""The runner a worker process keeps for its run (built at its first trial)."""


def run_trial_job(job: TrialJob) -> TrialRecord:
    """Runs one trial in a worker process (:mod:`sim.jobs` limits it to one torch thread)."""
    settings = job.settings
    if not _WORKER_RUNNER or _WORKER_RUNNER[0][0] != settings:
        for _, old in _WORKER_RUNNER:
            old.close()
        model = load_trial_model(settings)
        _WORKER_RUNNER[:] = [(settings, TrialRunner(
            settings.task_spec, model.factory, settings.settle_s, settings.execution,
            obstacles=settings.obstacles))]
    runner = _WORKER_RUNNER[0][1]
    return runner.run(_scene(settings, job.index), job.index, settings.seed, settings.model)


def _scene(settings: TrialSettings, index: int) -> Scene:
    """Trial ``index``'s scene: test scene ``index`` of the run's seed."""
    return sample_scene(settings.task_spec, YUMI_SCENE, settings.seed, SeedStream.TEST, index)


def _write_summary(settings: TrialSettings, log: TrialLog, out: Path,
                   session: dict[str, Any]) -> TrialSummary:
    """Writes ``summary.json`` of the trials ``log`` holds; their summary."""
    summary = log.summary(settings.n)
    check = held_out_check(settings)
    data = {"settings": settings.identity() | {"n": settings.n}} | summary.to_dict() | {
        "held_out_check": None if check is None else check.to_json(), "provenance": session}
    text = json.dumps(data, indent=2, sort_keys=True) + "\n"
    atomic_write(out / "summary.json", lambda temporary: temporary.write_text(text))
    return summary

