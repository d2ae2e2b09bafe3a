"""The perception model of a pick, by the name a trial gives it, built and checked.

A trial names its model by a string: ``"oracle"`` (or ``"oracle-view"``), built in and reading
the world; a checkpoint folder (``gva train`` writes one), checked against the task before the
first trial; a model of your own built with no arguments, ``"package.module:Class"`` or the
name an installed package registers (:mod:`perception.plugins`); or ``ws://HOST:PORT`` of a
served one. A model that uses torch runs its inference on one torch thread: a trial predicts one
image at a time, where more threads cost more than they save, and runs of trials side by side
would fight for the cores. A run's settings (:mod:`harness.inputs.trial_settings`) name the
model; the Gymnasium environment's model policy builds one here too.
"""

from __future__ import annotations

import contextlib
import enum
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from perception.checks import check_inputs
from perception.interface import PerceptionModel
from perception.learning.learnable import LearnableModel
from perception.plugins import build_plugin, installed_models, is_class_path, plugin_class
from perception.remote.client import RemoteModel, announced_metadata, is_remote
from robots.description import RobotDescription
from sim.errors import InvalidInputError
from sim.tasks.task_spec import TaskSpec
from sim.trials.model_fit import check_model_fits_task, recorded_sensor
from sim.trials.oracle import OraclePerception, ViewLimitedOracle
from sim.trials.runner_hooks import TRIAL_INPUTS, ModelFactory
from sim.world.sensor import SensorConfig

TRIAL_MODELS: dict[str, ModelFactory] = {"oracle": OraclePerception,
                                         "oracle-view": ViewLimitedOracle}
"""Perception models the trial runner builds by name; a checkpoint folder or
``"package.module:Class"`` names any other (see
:func:`harness.inputs.trial_settings.load_trial_model`)."""

_ALLOWED_MODELS = (f"one of {', '.join(TRIAL_MODELS)}, a checkpoint folder (gva train writes one), "
                   "'package.module:Class', the name an installed package registers in "
                   "'gva.models', or ws://HOST:PORT of a gva serve server")


class ModelSource(enum.Enum):
    """Where the model of a run of trials comes from."""

    BUILT_IN = "built_in"  # a name in TRIAL_MODELS
    CHECKPOINT = "checkpoint"  # a checkpoint folder of a learnable model
    CLASS = "class"  # "package.module:Class" or an installed plug-in's name: built with no
    # arguments
    REMOTE = "remote"  # ws://HOST:PORT: a model served elsewhere (gva serve)


def model_source(model: str) -> ModelSource:
    """Where ``model`` (a name, a folder or ``"package.module:Class"``) comes from."""
    if not isinstance(model, str) or not model:
        raise InvalidInputError("model", model, _ALLOWED_MODELS)
    if model in TRIAL_MODELS:
        return ModelSource.BUILT_IN
    if is_remote(model):
        return ModelSource.REMOTE
    if Path(model).is_dir():
        return ModelSource.CHECKPOINT
    if is_class_path(model) or model in installed_models():
        return ModelSource.CLASS
    raise InvalidInputError("model", model, _ALLOWED_MODELS)


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


def checked_model(model: str, task: TaskSpec, robot: RobotDescription,
                  model_class: str | None = None, allow_sensor_change: bool = False,
                  announced: Mapping[str, Any] | None = None) -> PerceptionModel:
    """:func:`built_model`, checked as ``gva trials`` and the env's model policy check it.

    It may read only what a trial gives, and must fit ``task`` and ``robot``.
    """
    built = built_model(model, model_class, announced)
    check_inputs(built, TRIAL_INPUTS, model)
    check_model_fits_task(built, task, model, allow_sensor_change, robot=robot)
    return built


def built_model(model: str, model_class: str | None = None,
                announced: Mapping[str, Any] | None = None) -> PerceptionModel:
    """The model ``model`` names (not a built-in one: those read the world), unchecked.

    A served model (``announced``: what it announced, if known), a checkpoint (loaded by
    ``model_class``, if given) or a plug-in without weights.

    Raises:
        InvalidInputError: It cannot be found or built, or is a learnable class (its
            checkpoint folder is what loads); one line.

    """
    source = model_source(model)
    if source is ModelSource.BUILT_IN:
        raise InvalidInputError("model", model, "a model that reads no simulator (built-in "
                                f"ones: {', '.join(TRIAL_MODELS)}, read the world)")
    if source is ModelSource.REMOTE:
        return RemoteModel(model, announced=announced)
    if source is ModelSource.CHECKPOINT:
        from perception.registry import load_model  # imports torch: not for the oracle

        return load_model(model, model_class)
    if issubclass(plugin_class(model), LearnableModel):
        raise InvalidInputError("model", model, "a model without weights; a learnable one "
                                f"loads from its checkpoint folder: --model FOLDER --model-class "
                                f"{model}")
    return build_plugin(model)


def checkpoint_sensor(model: str, announced: Mapping[str, Any] | None = None
                      ) -> SensorConfig | None:
    """The sensor checkpoint ``model`` was trained under, in a folder or served; else None.

    Read from its ``config.json`` (its spec's record, as :func:`trained_sensor` reads it), the
    weights unread, or from the spec its server announced (``ws://``: a served checkpoint is
    tried under its own sensor as in-process; ``announced``: what it announced, if known); None
    too where no spec is kept or announced (a model of its own making, unchecked) or a config
    cannot be read (loading it then says why).

    Raises:
        perception.errors.InvalidInputError: ``ws://`` names no reachable server; one line.

    """
    source = model_source(model)
    if source is ModelSource.REMOTE:
        spec = (announced if announced is not None else announced_metadata(model)).get("spec")
        return recorded_sensor(spec.get("sensor"), model) if isinstance(spec, dict) else None
    if source is not ModelSource.CHECKPOINT:
        return None
    from perception.learning.checkpoint import CheckpointError, read_config

    try:
        spec = read_config(model).get("spec")
    except CheckpointError:
        return None
    if not isinstance(spec, dict):
        return None
    return recorded_sensor(spec.get("sensor"), model)


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
