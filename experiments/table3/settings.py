"""What ``gva reproduce real`` runs: settings, units, trial sets, and where a folder keeps them.

A unit is one model on one task (trained, or a plug-in tried as it is); a trial set is a
unit's trials under a variant (as trained, or under one of the run's variants: darker light,
the block, other looks). Each seed's run has its own folder ``OUT/s<seed>/``.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

from experiments.table3.layout import checkpoint_folder, task_file
from experiments.table3.options import REAL
from experiments.table3.plugins import check_plugins, is_plugin, row, served_models
from experiments.tables import (
    ALL_TASKS,
    TASKS,
    check_choices,
    check_counts,
    check_model_configs,
    check_models,
    model_config,
    model_settings,
)
from harness.inputs.collector import CollectSettings, LabelSource, LookSource
from harness.inputs.trial_settings import TrialSettings, obstacle_identity, task_identity
from harness.jobs import LOCAL, Executor
from harness.run_folder import json_form
from perception.learning.train import TrainConfig, available_threads
from perception.learning.validation import CheckConfig
from perception.model_config_file import ModelConfigFile
from perception.remote.client import announced_metadata
from robots import DEFAULT_ROBOT, robot_identity
from robots.description import RobotDescription
from sim.errors import InvalidInputError
from sim.tasks.scene_sampling import SeedStream
from sim.tasks.task_spec import TaskSpec, spaced_for
from sim.tasks.task_toml import load_task
from sim.tasks.variants import read_variant, with_variant
from sim.trials.closed_loop.loop_settings import Loop, LoopSettings
from sim.trials.execution import ExecutionSettings
from sim.world.head_camera import CameraConfig, camera_config
from sim.world.robot_choice import resolve_robot
from sim.world.sensor import SensorConfig, SensorKind

SCENE = "yumi"
REFERENCE_MODEL = "kqv"
"""The model every baseline is compared with, trial for trial (the paper's)."""
PLAIN = "plain"
"""A unit's trials in the world it was trained in."""
OPEN_LOOP = "open-loop"
"""A closed-loop run's checkpoint, its picks open-loop on the same scenes (issue 36)."""
DEFAULT_VARIANTS = ("dark", "block")
"""The variants every model is tried under by default: the paper's robustness rows, darker
light and the wooden block (``sim/tasks/variants/``)."""
GIF_TRIALS = 3
RANDOMISED_SEED_OFFSET = 100
"""A seed's randomised scenes (``--randomised-scenes``) are drawn at seed + this, on the TRAIN
stream: never the demonstrations' own scenes (seed, TRAIN) nor any trial's (TEST stream, which
no collection of this run draws from); 100 is the offset appearance.md's offline measure drew
at (seed 110 beside seed 10's demonstrations)."""
FORMAT_VERSION = 3
"""What a run folder holds; 2: a demonstration keeps the image before each of its picks;
3: a folder per seed, and a scene with a condition shown under each of its values."""


def variant_task(task: str, variant: str, sensor: SensorKind = SensorKind.IDEAL,
                 world: str | None = None) -> TaskSpec:
    """The task ``task`` seen through ``sensor``, in ``world``, under ``variant``.

    ``world`` (a variant, ``--world``) is laid over the task first, then ``variant`` (one of
    the run's ``--variants``; ``plain`` and ``open-loop`` lay nothing): the same scenes, looked
    at otherwise, so the objects, poses, targets and conditions stay those of the plain task.
    The plain task's checkpoint serves every variant: trials check a model against the task's
    scene, condition, targets and image size, not its name or looks.
    """
    base = replace(load_task(task), camera=SensorConfig(sensor))
    if world is not None:
        base = with_variant(base, world)
    return base if variant in (PLAIN, OPEN_LOOP) else with_variant(base, variant)


@dataclass(frozen=True)
class Unit:
    """One model on one task: trained on it, or a plug-in tried as it is (:mod:`.plugins`)."""

    model: str
    task: str

    @property
    def name(self) -> str:
        """``kqv-single``: the stem of the unit's files."""
        return f"{self.model}-{self.task}"


@dataclass(frozen=True)
class TrialSet:
    """The trials of one unit under one variant (``plain``, ``open-loop`` or a variant's name)."""

    unit: Unit
    variant: str = PLAIN

    @property
    def task_name(self) -> str:
        """``single``, or ``single-dark``: the name of the folder and file of the set's task."""
        suffix = "" if self.variant == PLAIN else f"-{Path(self.variant).stem}"
        return f"{self.unit.task}{suffix}"

    @property
    def name(self) -> str:
        """``kqv-single-dark``: the stem of the set's files."""
        return f"{self.unit.model}-{self.task_name}"


@dataclass(frozen=True)
class ReproduceRealSettings:
    """What ``gva reproduce real`` runs; its fields' defaults are the command's.

    Args:
        models: Models to train, names :func:`~perception.registry.new_model` takes, or tried
            untrained on the same scenes: plug-ins without weights (``package.module:Class``)
            and served models (``ws://HOST:PORT``; :mod:`experiments.table3.plugins`).
        tasks: Tasks, from :data:`~experiments.tables.ALL_TASKS` (default: the paper's).
        n: Trials per model and task (the paper's 30).
        demos: Demonstrations per task (the paper's 20).
        steps: Optimiser steps of training.
        seed: S0: seeds the demonstrations (TRAIN stream), the weights and the trials (TEST
            stream); with ``seeds`` > 1 the first of the seeds.
        seeds: Runs of the whole experiment, seeds ``S0 .. S0 + seeds - 1``.
        variants: The variants every unit is also tried under (``--variants``: built-in names of
            :mod:`sim.tasks.variants` or variant files), each paired with its plain trials;
            by default the paper's robustness rows, darker light and the wooden block.
        balance_types: Demonstrations of a task whose scenes draw one object type take the
            types in turn (``objects.balance_types``), as the person recording the paper's
            demonstrations would; at random, 20 of ``single`` at seed 10 hold 2 sponges
            (docs/decisions/distractor.md). Trials' scenes are the same either way.
        sensor: What the head camera renders through, for demonstrations and trials alike
            (:class:`~sim.world.sensor.SensorKind`): the D435-like sensor by default, as the
            paper's robot saw; the ideal pinhole is the world of earlier tables.
        workers: Processes at once; None: the cores this process may use.
        executor: Where the jobs run: this machine's process pool (default) or Ray
            (:class:`~harness.jobs.Executor`); the results are the same.
        check: How each training checks itself on demonstrations it holds out
            (:class:`~perception.learning.validation.CheckConfig`); a model that fails is
            marked in its checkpoint and in the tables.
        gif_trials: The first trials of each unit's plain set recorded again as a GIF; 0: none
            (a sweep of many seeds may want none: each is a pick run twice).
        use_failed_checkpoints: Run the trials of a checkpoint that failed its held-out check
            at every start anyway, with a warning (for studies; what runs did before issue
            66). False: they are not run, and the cells are recorded failed with the check's
            reason (:mod:`.check_gate`). Part of no identity: a folder resumes either way.
        train_threads: Torch threads of each training job: 1 lets units train side by side; a
            one-unit run (``make demo``) trains twice as fast on two. Results depend on it
            (float sums in another order): part of a checkpoint's identity.
        model_configs: Settings of some of ``models`` read from files (``--model-config
            MODEL=FILE.toml``), at most one per model. They reach ``new_model`` and the
            model's hyper-parameters in each checkpoint's identity, so a folder trained with
            other settings is refused; with none, identities are as before files existed.
        loop: Closed (``--loop closed``): the demonstrations keep images along each approach
            at ``replan_hz`` (the arm in view), every trial set runs closed-loop, and each
            unit's checkpoint is also tried open-loop on the same scenes (``open-loop``), so
            the two compare pick by pick (:mod:`sim.trials.closed_loop.loop`). Open: as before.
        robot: The robot that demonstrates and picks, through its workcell's camera (one of
            :data:`robots.ROBOT_NAMES`, ``--robot``); named in the identity only where it is
            not the YuMi, so earlier folders resume.
        world: A variant every task of the run lives under, demonstrations and trials alike
            (``--world``, :mod:`sim.tasks.variants`; ``varied-held-out``: the generalisation
            protocol); named in the identity only where set. None: today's world.
        randomised_scenes: Scenes in randomised looks labelled by the catalog, collected per
            task beside its demonstrations (``--randomised-scenes``; what ``gva collect
            --labels catalog --looks randomised`` makes, of the run's task file, at
            :attr:`randomised_seed`), each trained unit trained on both as ``gva train --data
            DEMOS --data RANDOMISED`` is: the held-out check holds out demonstrations only, and
            the checkpoint records both files. Plug-ins and served models are not trained and
            take none. 0: none, and no identity names it, so earlier folders resume.

    """

    models: tuple[str, ...] = ("kqv",)
    tasks: tuple[str, ...] = TASKS
    n: int = TrialSettings.n
    demos: int = 20
    steps: int = TrainConfig.steps
    seed: int = 0
    seeds: int = 1
    variants: tuple[str, ...] = DEFAULT_VARIANTS
    balance_types: bool = True
    sensor: SensorKind = SensorKind.D435
    workers: int | None = None
    train_threads: int = 1
    executor: Executor = LOCAL
    check: CheckConfig = field(default_factory=CheckConfig)
    gif_trials: int = GIF_TRIALS
    use_failed_checkpoints: bool = False
    model_configs: tuple[ModelConfigFile, ...] = ()
    loop: LoopSettings = field(default_factory=LoopSettings)
    robot: str = DEFAULT_ROBOT
    world: str | None = None
    randomised_scenes: int = 0

    def __post_init__(self) -> None:
        if self.world is not None:
            read_variant(self.world)  # an unknown or malformed variant is refused by name
        names = [read_variant(variant)[0] for variant in self.variants]  # each refused by name
        for name in names:  # a variant's folder and row are its name: two of one name merge
            if name in (PLAIN, OPEN_LOOP) or names.count(name) > 1:
                raise InvalidInputError("variants", list(self.variants), "variants of distinct "
                                        f"names (a file's is its stem), none called {PLAIN} or "
                                        f"{OPEN_LOOP}")
        self.description()  # an unknown robot is refused, naming those allowed
        if not isinstance(self.use_failed_checkpoints, bool):
            raise InvalidInputError("use_failed_checkpoints", self.use_failed_checkpoints,
                                    "True or False")
        if not isinstance(self.sensor, SensorKind):
            raise InvalidInputError("sensor", self.sensor,
                                    f"one of {', '.join(k.value for k in SensorKind)}")
        check_models(self.models)
        check_plugins([m for m in self.models if is_plugin(m)], self.tasks, self.sensor,
                      self.robot)
        check_choices("tasks", self.tasks, ALL_TASKS)
        check_model_configs([(f.model, f.path) for f in self.model_configs], self.models)
        check_counts(self, {"n": 1, "demos": 1, "steps": 1, "seed": 0, "seeds": 1,
                            "train_threads": 1, "gif_trials": 0, "randomised_scenes": 0},
                     self.workers)
        if self.randomised_scenes and all(is_plugin(m) for m in self.models):
            raise InvalidInputError("randomised_scenes", self.randomised_scenes,
                                    "0 where no model is trained (plug-ins and served models "
                                    "are tried as they are)")

    @property
    def randomised_seed(self) -> int:
        """The seed the randomised scenes are drawn at: the run's + the offset.

        :data:`RANDOMISED_SEED_OFFSET` past the run's, on the TRAIN stream: never the
        demonstrations' scenes nor the trials'.
        """
        return self.seed + RANDOMISED_SEED_OFFSET

    def randomised_collect(self, task: str) -> CollectSettings:
        """What a task's randomised scenes are: ``task`` labelled by the catalog, randomised.

        ``task`` is its file, or a built-in's name; the scenes are drawn at
        :attr:`randomised_seed`, in randomised looks.
        """
        return CollectSettings(SCENE, task, self.randomised_scenes, self.randomised_seed,
                               SeedStream.TRAIN, robot=self.robot, labels=LabelSource.CATALOG,
                               looks=LookSource.RANDOMISED)

    @property
    def training_seeds(self) -> range:
        """S0 .. S0 + seeds - 1."""
        return range(self.seed, self.seed + self.seeds)

    def for_seed(self, seed: int) -> ReproduceRealSettings:
        """The settings of one seed's run (its folder is :func:`seed_folder`)."""
        return replace(self, seed=seed, seeds=1)

    def plugins(self) -> tuple[str, ...]:
        """The rows of the models tried untrained (:func:`.plugins.is_plugin`, :func:`.row`)."""
        return tuple(row(model) for model in self.models if is_plugin(model))

    def units(self) -> list[Unit]:
        """Every unit: models in the given order, tasks in the paper's, then those beyond it."""
        return [Unit(row(m), t) for m in self.models for t in ALL_TASKS if t in self.tasks]

    def trial_sets(self) -> list[TrialSet]:
        """Every set of trials: each unit's plain set, open-loop (closed runs), each variant."""
        variants = (PLAIN, *((OPEN_LOOP,) if self.closed else ()), *self.variants)
        return [TrialSet(unit, v) for unit in self.units() for v in variants]

    @property
    def closed(self) -> bool:
        """Whether the run's picks close the loop."""
        return self.loop.loop is Loop.CLOSED

    @property
    def approach_hz(self) -> float | None:
        """The rate of the demonstrations' approach images: a closed loop's, else none."""
        return self.loop.replan_hz if self.closed else None

    def run_task(self, trial_set: TrialSet) -> TaskSpec:
        """The task a set's trials run (and, plain, its demonstrations): variant and sensor.

        Its training scenes take the types in turn where ``balance_types`` says so; its objects
        are spaced for the robot's hand (:func:`~sim.tasks.task_spec.spaced_for`).
        """
        task = spaced_for(variant_task(trial_set.unit.task, trial_set.variant, self.sensor,
                                       self.world), self.description().neighbour_spacing_m)
        if self.balance_types and task.draws_one_type and not task.balance_types:
            task = replace(task, balance_types=True)
        return task

    def worker_count(self) -> int:
        """The processes to run: ``workers``, or the cores this process may use."""
        return self.workers if self.workers is not None else available_threads()

    def train_config(self) -> dict[str, Any]:
        """The training settings of every unit, on ``train_threads`` torch threads."""
        return asdict(TrainConfig(steps=self.steps, seed=self.seed, threads=self.train_threads))

    def run_identity(self) -> dict[str, Any]:
        """What every job of one seed's folder shares; its ``run.json`` holds it."""
        return self.shared_identity() | {"seed": self.seed, "train": self.train_config()}

    def shared_identity(self) -> dict[str, Any]:
        """What every seed of a run folder shares; ``OUT/run.json`` holds it.

        The sensor is there only when it is not the ideal camera, so folders from before
        sensors existed (all ideal) keep their identity.
        """
        train = self.train_config()
        train.pop("seed")  # each seed's own
        sensor = ({} if self.sensor is SensorKind.IDEAL
                  else {"sensor": SensorConfig(self.sensor).to_json()})
        loop = {"loop": self.loop.to_json()} if self.closed else {}
        robot = robot_identity(self.robot)
        world = {} if self.world is None else {"world": read_variant(self.world)[1]}
        randomised = ({} if not self.randomised_scenes
                      else {"randomised_scenes": self.randomised_scenes})
        return sensor | loop | robot | world | randomised | {
                "format_version": FORMAT_VERSION, "experiment": "reproduce-real",
                "scene": SCENE, "demos": self.demos, "n": self.n,
                "train": train, "settle_s": TrialSettings.settle_s,
                "execution": asdict(ExecutionSettings()), "gif_trials": self.gif_trials,
                "obstacles": obstacle_identity(TrialSettings.obstacles),
                "variants": {Path(v).stem: read_variant(v)[1] for v in self.variants}}

    def train_identity(self, unit: Unit) -> dict[str, Any]:
        """What defines a unit's checkpoint; ``trained.json`` holds it.

        Its randomised scenes (how many, their seed, labels and looks) only where there are
        some, so checkpoints trained before they existed keep their identity.
        """
        randomised = {} if not self.randomised_scenes else {"randomised_scenes": {
            "scenes": self.randomised_scenes, "seed": self.randomised_seed,
            **self.randomised_collect(unit.task).recorded()}}
        return json_form(randomised | {"model": unit.model,
                          "model_config": model_config(unit.model, self.seed,
                                                       self.model_settings(unit.model)),
                          "task": task_identity(self.run_task(TrialSet(unit))), "demos": self.demos,
                          "camera": asdict(self.camera_config()), "seed": self.seed,
                          "train": self.train_config(), "check": asdict(self.check)})

    def description(self) -> RobotDescription:
        """The robot that picks: ``robot`` resolved, the one place this run names it by name."""
        return resolve_robot(self.robot)

    def camera_config(self) -> CameraConfig:
        """The camera the run's demonstrations and trials see through: its robot's."""
        return camera_config(self.description())

    def model_settings(self, model: str) -> dict[str, Any]:
        """The settings ``model_configs`` give ``model`` (``new_model``'s keywords); {}: none."""
        return model_settings(self.model_configs, model)

    def trial_settings(self, out: Path, trial_set: TrialSet) -> TrialSettings:
        """A set's TrialSettings: checkpoint, plug-in, or served (with what it announced)."""
        unit, url = trial_set.unit, served_models(self.models).get(trial_set.unit.model)
        model = url or (unit.model if unit.model in self.plugins() else
                        str(checkpoint_folder(out, unit)))
        return TrialSettings(model=model, task=str(task_file(out, trial_set.task_name)),
                             n=self.n, seed=self.seed, loop=self.trial_loop(trial_set),
                             robot=self.robot,
                             announced=None if url is None else dict(announced_metadata(url)))

    def trial_loop(self, trial_set: TrialSet) -> LoopSettings:
        """The loop a set's picks run: the run's, but open for its ``open-loop`` sets."""
        return LoopSettings() if trial_set.variant == OPEN_LOOP else self.loop

    def command(self, out: Path) -> str:
        """The ``gva reproduce real`` command line of these settings (workers left out).

        Derived from the options' one table, :data:`experiments.table3.options.REAL`.
        """
        return REAL.line(self, out)
