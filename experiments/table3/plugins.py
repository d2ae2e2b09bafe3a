"""Plug-in models in ``gva reproduce real``: tried as they are, on the trained models' scenes.

A ``--models`` entry ``package.module:Class`` whose class has no weights (not a
:class:`~perception.learning.learnable.LearnableModel`; ``docs/plugins.md``) needs no
demonstrations or training: its trial sets run the same task files, seeds and trial indices as
a trained model's, so the reports pair it with them unchanged. A learnable class named so is
trained as before. A plug-in is named and checked the way ``gva trials --model`` names and
checks it (:func:`~harness.inputs.trial_settings.load_trial_model`), so its trial folders record
the identity ``gva trials`` records.

A served model (``ws://HOST:PORT``, ``gva serve``) joins the same way. Its row (and folders) is
named ``<announced name>@<address>`` (:func:`served_row`); its trial sets record what the
server announced when the run began, so a rerun against a server announcing another model under
that row is refused before any job. The server must answer when the run starts (as ``gva
trials`` asks); once it has, a server that is down costs the trials that need it
(``perception_failed``), never a job or the run.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from typing import Any
from urllib.parse import urlsplit

from experiments.tables import allowed_models
from harness.inputs.trial_settings import TrialSettings, load_trial_model
from perception.errors import InvalidInputError as PluginError
from perception.learning.learnable import LearnableModel
from perception.plugins import is_class_path, plugin_class
from perception.remote.client import announced_metadata, is_remote
from sim.errors import InvalidInputError
from sim.world.sensor import SensorKind


def is_plugin(model: str) -> bool:
    """Whether ``model`` (a ``--models`` entry) is a plug-in tried untrained.

    True for ``package.module:Class`` of a class without weights and for a served model
    (``ws://HOST:PORT``); False for a registered name or preset, and for a learnable class
    (trained like a registered model).

    Raises:
        InvalidInputError: ``model`` is ``package.module:Class`` and the class cannot be found
            (its module does not import, it lacks the class, or the class is no model); the
            message names ``models``, the spec and why.

    """
    if is_remote(model):
        return True
    if model in allowed_models() or not is_class_path(model):
        return False
    try:
        cls = plugin_class(model)
    except PluginError as error:
        raise InvalidInputError("models", model, f"one of {', '.join(allowed_models())}, or "
                                f"'package.module:Class' of a model ({error.allowed})") from None
    return not issubclass(cls, LearnableModel)


def check_plugins(plugins: Sequence[str], tasks: Sequence[str], sensor: SensorKind,
                  robot: str) -> None:
    """Raises unless each plug-in serves each task as ``gva trials --model SPEC`` requires.

    Each is built and checked against each task by
    :func:`~harness.inputs.trial_settings.load_trial_model` (built with no arguments, a name, the
    inputs a trial gives, grasp poses), in a few milliseconds: a run refuses a plug-in before
    it writes anything, with the message ``gva trials`` gives.
    """
    for plugin in plugins:
        for task in tasks:
            load_trial_model(TrialSettings(model=plugin, task=task, n=1, sensor=sensor,
                                           robot=robot))


def served_row(url: str, announced: Mapping[str, Any]) -> str:
    """The row of a served model: its announced name at its address (``kqv@host:8000``).

    A file name too (the row names its trial folders and jobs): characters other than letters,
    digits and ``._:@+-`` become ``-``; a server that announces no name is ``served``.
    """
    parts = urlsplit(url)
    name = announced.get("name")
    row = f"{name if isinstance(name, str) and name else 'served'}@{parts.netloc}{parts.path}"
    return re.sub(r"[^A-Za-z0-9._:@+-]", "-", row.rstrip("/"))


def row(model: str) -> str:
    """The row (and unit) of a ``--models`` entry: itself, or a served model's :func:`served_row`.

    A served model's from what its server announced (asked once per process).
    """
    return served_row(model, announced_metadata(model)) if is_remote(model) else model


def served_models(models: Sequence[str]) -> dict[str, str]:
    """Each served model of ``models``: its row and address."""
    return {row(model): model for model in models if is_remote(model)}
