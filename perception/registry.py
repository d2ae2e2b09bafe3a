"""Perception models by name: the built-in ones, or your own (:mod:`perception.plugins`).

::

    model_class("kqv")                      # -> KqvModel
    model_class("my_lab.models:TinyNet")    # imported with importlib; must be a PerceptionModel
    model_class("tiny-net")                 # a name an installed package registers (gva.models)
    new_model("keypoint-16", dataset, seed=0)   # a fresh model for a dataset, preset applied
    resolve_model_config("keypoint-16", 0, {"lr": 1e-3})  # -> (KeypointModel, its checked config)
    load_model("runs/kqv-single")           # reads config.json's model name, then Class.load

A checkpoint names its model but never says where to import code from: loading a checkpoint of
a model that is not registered needs the class named by the caller (``load_model(folder,
"my_lab.models:TinyNet")``), so opening a file never imports a module the file chose.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from pathlib import Path
from types import MappingProxyType
from typing import Any, NamedTuple

from perception.interface import InvalidInputError, PerceptionModel
from perception.learning.checkpoint import CONFIG_FILE, CheckpointError, read_config
from perception.learning.data import Dataset
from perception.learning.learnable import LearnableModel
from perception.models.conv_ae import ConvAeModel
from perception.models.dsae import DsaeModel
from perception.models.fcn import FcnModel
from perception.models.keypoint import KeypointModel
from perception.models.kqv import KqvModel
from perception.models.kqv_config import PAPER as PAPER_KQV
from perception.models.torch_model import TorchModel
from perception.plugins import (
    ENTRY_POINT_GROUP,
    installed_models,
    is_class_path,
    plugin_class,
)

MODELS: Mapping[str, type[PerceptionModel]] = MappingProxyType({
    KqvModel.name: KqvModel,
    KeypointModel.name: KeypointModel,
    DsaeModel.name: DsaeModel,
    ConvAeModel.name: ConvAeModel,
    FcnModel.name: FcnModel,
})
"""The built-in models by name; adding a model adds one line here."""

PRESETS: Mapping[str, tuple[str, Mapping[str, Any]]] = MappingProxyType({
    "keypoint-16": ("keypoint", {"points": 16}),  # paper Table II: Key Point (q=16)
    "keypoint-min": ("keypoint", {"points": None}),  # Key Point (q=min): one point per target
    "dsae-16": ("dsae", {"points": 16}),  # Deep Spatial AE (q=16)
    # kqv read out by the paper's MLP of the attention point and feature, not the camera's ray:
    # the readout's share of kqv's grasps (docs/decisions/d435-sensor.md, error by radius)
    "kqv-mlp": ("kqv", {"readout": "mlp"}),
    # the paper's model as written (perception.models.kqv_config.PAPER, a sentence per setting)
    "kqv-paper": ("kqv", PAPER_KQV),
    # helped: kqv's ray readout + point loss on its points, per-image scaling, mirror where allowed
    "keypoint-16-helped": ("keypoint", {"points": 16, "readout": "ray", "point_loss_weight": 10.0,
                                        "input_norm": "per-image", "mirror": None}),
    # helped (q=min): the same help, point k read as target k (mirror None: the collector's flag)
    "keypoint-min-helped": ("keypoint", {"points": None, "readout": "ray",
                                         "point_loss_weight": 10.0, "input_norm": "per-image",
                                         "mirror": None}),
    # helped where a model without attention points can be: per-image scaling, mirror allowed
    "fcn-helped": ("fcn", {"input_norm": "per-image", "mirror": None}),
})
"""Named variants of a built-in model: name -> (model, hyper-parameters it sets)."""


class Trainable(NamedTuple):
    """What a model name trains: its class, and the settings its preset gives (none: empty)."""

    cls: type[TorchModel]
    preset: Mapping[str, Any]


def trainable(name_or_path: str) -> Trainable:
    """The class and preset settings behind a name :func:`new_model` takes.

    One place resolves a name for training, for a run's identities and for a model config
    file, so the three cannot disagree about what a preset sets.

    Raises:
        InvalidInputError: An unknown model, or one that does not train from a dataset.

    """
    base, preset = PRESETS.get(name_or_path, (name_or_path, MappingProxyType({})))
    cls = model_class(base)
    if not issubclass(cls, TorchModel):
        raise InvalidInputError("model", name_or_path, "a model that trains from a dataset "
                                f"(a TorchModel: {_names()}, or a subclass of your own)")
    return Trainable(cls, preset)


class ResolvedModel(NamedTuple):
    """A model name resolved: its class, and the checked config it is built with."""

    cls: type[TorchModel]
    config: Any  # an instance of cls.config_class


def resolve_model_config(name_or_path: str, seed: int | None,
                         overrides: Mapping[str, Any] | None = None) -> ResolvedModel:
    """The class and config a model is built with: its preset, then ``overrides``, then ``seed``.

    The one place that merges them: :func:`new_model` builds with it, a run's identities record
    it (:func:`experiments.tables.model_config`), a model config file is checked with it
    (:func:`perception.model_config_file.read_model_config`).

    Args:
        name_or_path: As :func:`new_model` takes it.
        seed: Seeds the initial weights; None: the config's own default (a model config
            file's check, which sets no seed).
        overrides: Fields of the config that differ from the defaults and the preset's.

    Raises:
        InvalidInputError: An unknown model, one that does not train from a dataset, a field
            the model's config does not have (the message lists those it has), or a value the
            config refuses.

    """
    cls, preset = trainable(name_or_path)
    settings = {**preset, **(overrides or {})} | ({} if seed is None else {"seed": seed})
    allowed = [field.name for field in dataclasses.fields(cls.config_class)]
    if unknown := sorted(set(settings) - set(allowed)):
        raise InvalidInputError("hyper-parameters", unknown, f"fields of {cls.name}'s "
                                f"{cls.config_class.__name__}: {', '.join(allowed)}")
    return ResolvedModel(cls, cls.config_class(**settings))


def new_model(name_or_path: str, dataset: Dataset, *, seed: int = 0,
              **hyperparameters: Any) -> LearnableModel:
    """A fresh, untrained model for ``dataset``'s task, its weights seeded with ``seed``.

    Args:
        name_or_path: A registered name, a preset (:data:`PRESETS`, e.g. ``"keypoint-16"``) or
            ``"package.module:Class"`` of a :class:`~perception.models.torch_model.TorchModel`.
        dataset: The training dataset; its metadata sets label kind, q, condition, image size.
        seed: Seeds the initial weights.
        **hyperparameters: Fields of the model's config dataclass that differ from the defaults
            (and from the preset's).

    Raises:
        InvalidInputError: An unknown model, a model that cannot be built from a dataset, or a
            hyper-parameter the model's config does not have (the message lists those it has).

    """
    cls, config = resolve_model_config(name_or_path, seed, hyperparameters)
    return cls.for_dataset(dataset, config)


def model_class(name_or_path: str) -> type[PerceptionModel]:
    """The model class a built-in name, an installed plug-in's name or a path names.

    A name that is not built in is looked up as :func:`perception.plugins.plugin_class` does:
    ``"package.module:Class"``, or a name an installed package registers.

    Raises:
        InvalidInputError: An unknown name, a module that does not import, a missing class or a
            class that is not a :class:`PerceptionModel`; the message says which.

    """
    if not isinstance(name_or_path, str) or not name_or_path:
        raise InvalidInputError("model", name_or_path, f"a registered name ({_names()}) or "
                                "'package.module:Class'")
    if name_or_path in PRESETS:
        name_or_path = PRESETS[name_or_path][0]
    if name_or_path in MODELS:
        return MODELS[name_or_path]
    if not is_class_path(name_or_path) and name_or_path not in installed_models():
        installed = ", ".join(installed_models()) or "none installed"
        raise InvalidInputError("model", name_or_path, f"a registered name ({_names()}), a "
                                f"name an installed package registers in {ENTRY_POINT_GROUP!r} "
                                f"({installed}), or 'package.module:Class' for a model of "
                                "your own")
    return plugin_class(name_or_path)


def load_model(folder: str | Path, model: str | None = None) -> LearnableModel:
    """The model saved in checkpoint ``folder``.

    Args:
        folder: A checkpoint folder (``config.json`` + ``weights.safetensors``).
        model: The class to load with, as for :func:`model_class`; None: the registered model
            ``config.json`` names. Needed for a model that is not registered.

    Raises:
        CheckpointError: The folder is not a usable checkpoint, or it names an unregistered
            model and ``model`` was not given.
        InvalidInputError: ``model`` names no learnable model.

    """
    config = read_config(folder)
    if model is None:
        if config["model"] not in MODELS:
            raise CheckpointError(Path(folder) / CONFIG_FILE, f"names model {config['model']!r}"
                                  f", which is not registered ({_names()}); pass "
                                  "model='package.module:Class' to load it with your own class")
        model = config["model"]
    cls = model_class(model)
    if not issubclass(cls, LearnableModel):
        raise InvalidInputError("model", model, "a LearnableModel (one with weights to load)")
    return cls.load(folder)


def _names() -> str:
    return ", ".join([*MODELS, *PRESETS])
