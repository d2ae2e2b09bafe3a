"""What both tables use (``gva reproduce sim``, Table II, and ``gva reproduce real``, Table III).

- the paper's tasks and models, their titles in the reports, and a model's hyper-parameters
  as a run folder records them (:func:`model_config`);
- settings checks (:func:`check_choices`, :func:`check_counts`).

A run folder's files, jobs' error files and the datasets a run reuses are the run layer's
(:mod:`harness.run_files`), as are a run's progress bar and report (:mod:`harness.run_report`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import asdict
from typing import Any

from perception.model_config_file import ModelConfigFile
from perception.registry import MODELS as REGISTERED
from perception.registry import PRESETS, resolve_model_config
from sim.errors import InvalidInputError

PAPER_MODELS = ("kqv", "keypoint-16", "keypoint-min", "dsae-16", "conv-ae", "fcn")
"""The paper's models, in its row order (names :func:`perception.registry.new_model` takes)."""
TASKS = ("single", "multiple", "selected-type", "selected-position")
"""The paper's tasks (its Table I), in its column order."""
BEYOND_TASKS = ("selected-type-text", "selected-position-text", "selected-type-image",
                "single-moved", "selected-type-moved")
"""Tasks beyond the paper: its selected tasks with the condition given as a sentence or a
picture, and targets moved while the arm approaches (issue 36)."""
ALL_TASKS = TASKS + BEYOND_TASKS
"""Every task the experiments run, in column order."""
TWO_PHASE_MODELS = ("dsae-16", "conv-ae")
"""Models trained in two phases (autoencoder, then targets): they take longer to train."""
NO_IMAGE = "no-image"
"""The row of :func:`perception.learning.evaluate.label_mean_error_cm` in Table II."""
MODEL_TITLES = {
    "kqv": "Ours (kqv, q=min)", "keypoint-16": "Key Point (q=16)",
    "keypoint-min": "Key Point (q=min)", "dsae-16": "Deep Spatial AE (q=16)",
    "conv-ae": "Convolutional AE", "fcn": "FCN",
    NO_IMAGE: "No image (training-label mean)",
    "kqv-paper": "The paper's model as written (kqv-paper)", "kqv-mlp": "Ours, MLP readout",
    "keypoint-16-helped": "Key Point (q=16), helped",
    "keypoint-min-helped": "Key Point (q=min), helped", "fcn-helped": "FCN, helped",
}
"""Each model's row title, in the tables' row order (the paper's models first)."""


def model_title(model: str) -> str:
    """The row title of ``model`` (a plug-in's own name where it has none)."""
    return MODEL_TITLES.get(model, model)


def model_order(model: str) -> tuple[int, str]:
    """Where ``model`` sorts in the tables: :data:`MODEL_TITLES`' order, then others by name."""
    known = list(MODEL_TITLES)
    return (known.index(model) if model in known else len(known), model)


def paper_row(model: str) -> str | None:
    """The row of the paper's tables that ``model`` stands beside, if any.

    A paper model's own; the paper's KQV for ``kqv-paper`` (that model as written); None for
    gva's variants and plug-ins.
    """
    return "kqv" if model == "kqv-paper" else model if model in PAPER_MODELS else None


def allowed_models() -> tuple[str, ...]:
    """The model names ``new_model`` takes: registered models and presets."""
    return (*REGISTERED, *PRESETS)


def check_models(models: Sequence[str]) -> None:
    """Raises unless ``models`` are distinct names ``new_model`` takes (or plug-in paths)."""
    custom = tuple(m for m in models if ":" in m)  # package.module:Class
    check_choices("models", models, (*allowed_models(), *custom))
TASK_TITLES = {"single": "Single Object", "multiple": "Multiple Objects",
               "selected-type": "Selected Type", "selected-position": "Selected Position",
               "selected-type-text": "Selected Type (sentence)",
               "selected-position-text": "Selected Position (sentence)",
               "selected-type-image": "Selected Type (picture)",
               "single-moved": "Single Object (moved)",
               "selected-type-moved": "Selected Type (moved)"}


def model_config(model: str, seed: int, settings: Mapping[str, Any] | None = None
                 ) -> dict[str, Any]:
    """The hyper-parameters ``new_model(model, dataset, seed=seed, **settings)`` builds with.

    As a dict, every field: a run folder's identities hold it, so a file that changes a setting
    (``--model-config``) changes them, and with no settings they are what they always were. A
    field the config class lists in ``SINCE`` (added later) is left out at the value that
    behaves as before it, so folders made before it still resume.
    """
    cls, resolved = resolve_model_config(model, seed, settings)
    config = asdict(resolved)
    since: Mapping[str, Any] = getattr(cls.config_class, "SINCE", {})
    return {key: value for key, value in config.items()
            if key not in since or value != since[key]}


def model_config_file(files: Sequence[ModelConfigFile], model: str) -> ModelConfigFile | None:
    """The file of ``files`` (``--model-config``, at most one per model) for ``model``, if any."""
    return next((file for file in files if file.model == model), None)


def model_settings(files: Sequence[ModelConfigFile], model: str) -> dict[str, Any]:
    """The settings ``files`` (``--model-config``) give ``model``; {}: none, its own.

    ``new_model``'s keywords, as both reproduce commands train and identify a model with them.
    """
    file = model_config_file(files, model)
    return {} if file is None else file.hyperparameters()


def check_model_configs(given: Sequence[tuple[str, str]], models: Sequence[str]) -> None:
    """Raises unless each ``(model, path)`` of ``--model-config`` names its own one of ``models``.

    Checked before any file is read: a file for a model the run does not train is a mistake.
    """
    names = [model for model, _ in given]
    for model, path in given:
        if model not in models or names.count(model) > 1:
            raise InvalidInputError("--model-config", f"{model}={path}",
                                    f"MODEL=FILE.toml, at most one per MODEL, MODEL one of "
                                    f"--models: {', '.join(models)}")


def model_config_options(files: Sequence[ModelConfigFile]) -> list[str]:
    """``--model-config MODEL=FILE`` per file: the options of a run's command line."""
    return [f"--model-config {file.model}={file.path}" for file in files]


# settings


def check_choices(name: str, values: Sequence[Any], allowed: Sequence[Any]) -> None:
    """Raises unless ``values`` is a non-empty list of distinct members of ``allowed``."""
    shown = ", ".join(str(a) for a in allowed)
    unknown = [v for v in values if v not in allowed]
    if not values or unknown or len(set(values)) != len(values):
        value = ",".join(str(v) for v in (unknown or values))
        raise InvalidInputError(name, value, f"distinct comma-separated values from {shown}")


def check_counts(settings: object, least: dict[str, int], workers: int | None) -> None:
    """Raises unless ``settings``' fields named in ``least`` are integers at least that large.

    ``workers`` must be None or an integer >= 1.
    """
    for name, minimum in least.items():
        value = getattr(settings, name)
        if not isinstance(value, int) or isinstance(value, bool) or value < minimum:
            raise InvalidInputError(name, value, f"an integer >= {minimum}")
    if workers is not None and (not isinstance(workers, int) or workers < 1):
        raise InvalidInputError("workers", workers, "None or an integer >= 1")

