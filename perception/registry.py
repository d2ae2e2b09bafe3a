"""Perception models by name: the built-in ones, or ``"package.module:Class"`` for your own.

::

    model_class("kqv")                      # -> KqvModel
    model_class("my_lab.models:TinyNet")    # imported with importlib; must be a PerceptionModel
    load_model("runs/kqv-single")           # reads config.json's model name, then Class.load

A checkpoint names its model but never says where to import code from: loading a checkpoint of
a model that is not registered needs the class named by the caller (``load_model(folder,
"my_lab.models:TinyNet")``), so opening a file never imports a module the file chose.
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from pathlib import Path
from types import MappingProxyType

from perception.checkpoint import CONFIG_FILE, CheckpointError, read_config
from perception.interface import InvalidInputError, PerceptionModel
from perception.learnable import LearnableModel
from perception.models.kqv import KqvModel

MODELS: Mapping[str, type[PerceptionModel]] = MappingProxyType({
    KqvModel.name: KqvModel,
})
"""The built-in models by name; adding a model adds one line here."""


def model_class(name_or_path: str) -> type[PerceptionModel]:
    """The model class a registered name or a ``"package.module:Class"`` path names.

    Raises:
        InvalidInputError: An unknown name, a module that does not import, a missing class or a
            class that is not a :class:`PerceptionModel`; the message says which.

    """
    if not isinstance(name_or_path, str) or not name_or_path:
        raise InvalidInputError("model", name_or_path, f"a registered name ({_names()}) or "
                                "'package.module:Class'")
    if ":" not in name_or_path:
        if name_or_path not in MODELS:
            raise InvalidInputError("model", name_or_path, f"a registered name ({_names()}) "
                                    "or 'package.module:Class' for a model of your own")
        return MODELS[name_or_path]
    module_name, _, class_name = name_or_path.partition(":")
    if not module_name or not class_name.isidentifier():
        raise InvalidInputError("model", name_or_path, "'package.module:Class' with both parts")
    try:
        module = importlib.import_module(module_name)
    except ImportError as error:
        raise InvalidInputError("model", name_or_path, f"an importable module; importing "
                                f"{module_name!r} failed: {error}") from error
    cls = getattr(module, class_name, None)
    if cls is None:
        raise InvalidInputError("model", name_or_path, f"a class that module {module_name!r} "
                                f"defines; it has no {class_name!r}")
    if not isinstance(cls, type) or not issubclass(cls, PerceptionModel):
        raise InvalidInputError("model", name_or_path, "a subclass of "
                                "perception.interface.PerceptionModel; "
                                f"{class_name} is {cls!r}")
    return cls


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
    return ", ".join(MODELS)
