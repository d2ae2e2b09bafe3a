"""``gva train``, ``gva evaluate`` and ``gva show attention``: the commands that load torch.

Each prints what a reader needs (one summary line, the file it wrote) and returns the exit
status; errors are raised for :func:`experiments.cli.main` to report in one line. Training
defaults are :class:`~perception.learning.train.TrainConfig`'s and
:class:`~perception.learning.validation.CheckConfig`'s.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from experiments.commands.arguments import integer
from experiments.commands.options import CommandLine, Option
from perception.drawing import AttentionRow, attention_figure, write_png
from perception.files import atomic_write
from perception.interface import ConditionKind, InvalidInputError, PerceptionError, Prediction
from perception.learning.checkpoint import CONFIG_FILE, WEIGHTS_FILE, read_config
from perception.learning.combined import PARTS_KEY, concatenate, training_files
from perception.learning.data import Dataset
from perception.learning.dataset_file import load_dataset
from perception.learning.evaluate import evaluate
from perception.learning.learnable import LearnableModel, ModelSpec
from perception.learning.train import TrainConfig
from perception.learning.validation import CHECK_FILE, CheckConfig, fit_checked, write_check
from perception.model_config_file import ModelConfigFile, settings_text
from perception.models.kqv import KqvModel
from perception.models.torch_model import TorchModel
from perception.registry import load_model, new_model
from perception.remote.client import RemoteModel, is_remote


def add_options(parser: argparse.ArgumentParser, command: str) -> None:
    """The options of ``command``: ``train``, ``evaluate`` or ``attention`` (gva show)."""
    if command == "train":
        _train_options(parser)
        parser.set_defaults(run=run_train)
        return
    if command == "evaluate":
        parser.add_argument("--model", required=True, help="checkpoint folder, or "
                            "ws://HOST:PORT of a model gva serve serves")
        parser.add_argument("--data", type=Path, required=True,
                            help="dataset file (test scenes)")
        parser.add_argument("--out", type=Path,
                            help="JSON file to write (MODEL/evaluation-<dataset name>.json; "
                            "needed for a served model)")
        parser.set_defaults(run=run_evaluate)
    else:
        parser.add_argument("--model", type=Path, required=True, help="checkpoint folder")
        parser.add_argument("--data", type=Path, required=True, help="dataset file")
        parser.add_argument("--out", type=Path, required=True, help="folder for the PNGs")
        parser.add_argument("--count", type=integer(1), default=8,
                            help="samples drawn (%(default)s)")
        parser.add_argument("--scale", type=integer(1), default=3,
                            help="enlarge the image this many times (%(default)s)")
        parser.set_defaults(run=run_show_attention)
    parser.add_argument("--model-class", metavar="MODULE:CLASS",
                        help="the class that loads a checkpoint of an unregistered model")


@dataclass(frozen=True)
class TrainCommand:
    """What ``gva train``'s options set: the training and its held-out check.

    Each default is the field's in :class:`~perception.learning.train.TrainConfig` and
    :class:`~perception.learning.validation.CheckConfig`: :data:`TRAIN_OPTIONS` reads them there.
    """

    train: TrainConfig = field(default_factory=TrainConfig)
    check: CheckConfig = field(default_factory=CheckConfig)


TRAIN_OPTIONS = CommandLine("gva train", rows=(
    Option("--seed", "seeds the weights and the batches ({default})", integer(0),
           field="train.seed"),
    Option("--steps", "optimiser steps ({default})", integer(1), field="train.steps"),
    Option("--batch-size", "samples per step ({default})", integer(1), field="train.batch_size"),
    Option("--threads", "torch CPU threads (default: OMP_NUM_THREADS, else the cores it may "
           "use)", integer(1), field="train.threads"),
    Option("--holdout", "fraction of the training scenes held out to check the trained model, "
           "of the demonstrations where other scenes are trained on beside them ({default}; "
           "0: no check)", float, field="check.holdout"),
    Option("--check-limit-cm", "largest held-out mean error, of the whole, each condition and "
           "each head [cm] ({default})", float, field="check.limit_cm"),
    Option("--check-min-expected", "least share of held-out targets expected picked (the mean "
           "of the grasp judge's calibrated probabilities), of the whole, each condition and "
           "each head (grasp labels; {default})", float, field="check.min_expected_success"),
    Option("--attempts", "trainings tried from other starts before the checkpoint is marked "
           "failed ({default})", integer(1), field="check.attempts"),
), order=("--seed", "--steps", "--batch-size", "--threads", "--holdout", "--check-limit-cm",
          "--check-min-expected", "--attempts"))
"""``gva train``'s options that set the training and its check, each declared once."""


def _train_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--model", required=True,
                        help="registered model, preset (keypoint-16) or package.module:Class")
    parser.add_argument("--data", type=Path, required=True, action="append",
                        help="training dataset file; again to train on several at once "
                        "(demonstrations, then a --labels catalog set): they must agree on "
                        "what the model reads and predicts, and the held-out check holds out "
                        "demonstrations only")
    parser.add_argument("--out", type=Path, required=True, help="checkpoint folder to write")
    parser.add_argument("--points", type=integer(1),
                        help="attention points of models that have the setting (keypoint)")
    parser.add_argument("--model-config", type=Path, metavar="FILE.toml",
                        help="TOML file of the model's settings, a top-level key per field of "
                        "its config (docs/perception.md); a key left out keeps the preset's "
                        "or the default value")
    TRAIN_OPTIONS.add_to(parser, TrainCommand)
    parser.add_argument("--overwrite", action="store_true",
                        help="replace a checkpoint already in --out")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def run_train(args: argparse.Namespace) -> int:
    """``gva train``: a fresh model, fitted on ``--data``, saved in ``--out``.

    Several ``--data`` files are joined (:func:`~perception.learning.combined.concatenate`)
    and recorded in the checkpoint; one file trains exactly as before several could be given.
    """
    out: Path = args.out
    if out.exists() and not out.is_dir():
        raise InvalidInputError("--out", str(out), "a folder for the checkpoint; it is a file")
    held = [name for name in (CONFIG_FILE, WEIGHTS_FILE) if (out / name).exists()]
    if held and not args.overwrite:
        raise InvalidInputError("--out", str(out), f"a folder without a checkpoint; it holds "
                                f"{' and '.join(held)} (pass --overwrite to replace them)")
    source = None if args.model_config is None else ModelConfigFile.read(args.model_config,
                                                                         args.model)
    hyperparameters = {} if source is None else source.hyperparameters()
    if args.points is not None and "points" in hyperparameters:
        raise InvalidInputError("--points", args.points, f"left out: --model-config "
                                f"{args.model_config} sets points too "
                                f"({hyperparameters['points']!r}); give it one way")
    if args.points is not None:
        hyperparameters["points"] = args.points
    paths: list[Path] = args.data
    dataset = load_dataset(paths[0]) if len(paths) == 1 else \
        concatenate([load_dataset(path) for path in paths], [str(path) for path in paths])
    chosen = TrainCommand(**TRAIN_OPTIONS.keywords(args, TrainCommand))
    config, check = chosen.train, chosen.check
    fit = fit_checked(lambda seed: new_model(args.model, dataset, seed=seed, **hyperparameters),
                      dataset, config, check, progress=not args.no_progress, log=print)
    model, report = fit.model, fit.report
    if source is not None:
        source.record(model)
    if len(paths) > 1 and isinstance(model, TorchModel):
        model.provenance["datasets"] = training_files(dataset, paths)
    model.save(out)
    write_check(out, fit)
    meta = dataset.metadata
    print(f"{model.name} on {meta.scene} / {meta.task}: {report.samples} samples, "
          f"{report.steps} steps, final loss {report.final_loss:.4g}, "
          f"{report.wall_time_s:.1f} s on {report.threads} thread(s)")
    if len(paths) > 1:
        print("trained on: " + " + ".join(
            f"{part['name']} ({part['task']}, {part['scenes']} scenes, {part['samples']} "
            f"samples, {part['labels']} labels, {part['looks']} looks)"
            for part in meta.extra[PARTS_KEY]))
    if len(report.phases) > 1:
        print("phases: " + "; ".join(f"{phase.name} {phase.steps} steps, final loss "
                                     f"{phase.final_loss:.4g}" for phase in report.phases))
    if source is not None:
        print(f"model config {source.path}: "
              f"{settings_text(source.hyperparameters()) or 'nothing set (the defaults)'}")
    print(f"checkpoint: {out}" + (" (replaced)" if held else ""))
    if fit.check is not None and not fit.check.passed:
        print(f"WARNING: {out} failed its held-out check after {len(fit.checks)} attempt(s): "
              f"{fit.check.reason}; the trials will say so (see {out / CHECK_FILE})",
              file=sys.stderr)
        return 1
    return 0


def run_evaluate(args: argparse.Namespace) -> int:
    """``gva evaluate``: a checkpoint's (or served model's) errors on ``--data``, as JSON too.

    A served model (``ws://HOST:PORT``) is sent each sample as a trial's frame; its JSON
    records the address and what the server announced where a checkpoint's records its path
    and weights' SHA-256.
    """
    served = is_remote(args.model)
    if served and args.out is None:
        raise InvalidInputError("--out", None, "a JSON file to write: a served model has no "
                                "checkpoint folder to write beside")
    model: LearnableModel | RemoteModel
    model, dataset = _served_and_dataset(args) if served else _model_and_dataset(args)
    result = evaluate(model, dataset, frames=served)
    print(result.headline())
    names = target_names(dataset)
    print("per target, mean position error: " + ", ".join(
        f"{_target(k, names)} {e:.2f} cm"
        for k, e in enumerate(result.per_target_mean_position_error_cm)))
    if result.per_target_mean_angle_error_deg is not None:
        print("per target, mean angle error: " + ", ".join(
            f"{_target(k, names)} {e:.1f}°"
            for k, e in enumerate(result.per_target_mean_angle_error_deg)))
    if len(result.per_stage_mean_position_error_cm) > 1:
        print("per pick stage (targets already picked), mean position error: " + ", ".join(
            f"{stage}: {e:.2f} cm" for stage, e in
            enumerate(result.per_stage_mean_position_error_cm)))
    if result.per_condition_mean_position_error_cm is not None:
        print("per condition, mean position error: " + ", ".join(
            f"{value} {e:.2f} cm" for value, e in
            result.per_condition_mean_position_error_cm.items()))
    if result.judged is not None:
        print("judged as a trial judges a pick (errors: mean/p95/worst):")
        judged = result.judged
        for title, groups in (("all", {"all": judged.all}), ("per object", judged.per_object),
                              ("per condition", judged.per_condition or {}),
                              ("per head", judged.per_head or {})):
            for name, group in groups.items():
                print(f"  {title + ' ' + name if title != 'all' else 'all':<28} {group.line()}")
    if result.median_heatmap_entropy_nats is not None:
        print(f"median heatmap entropy: {result.median_heatmap_entropy_nats:.2f} nats")
    if result.type_accuracy is not None:
        print(f"object type stated right: {100 * result.type_accuracy:.1f} % of targets")
    if result.attention_on_named_fraction is not None:
        print(f"attention on the named object: {100 * result.attention_on_named_fraction:.1f} "
              "% of images")
    if result.attention_switch_fraction is not None:
        print(f"attention moves to the named object under every condition: "
              f"{100 * result.attention_switch_fraction:.1f} % of scenes")
    out: Path = args.out or Path(args.model) / f"evaluation-{args.data.stem}.json"
    source: dict[str, Any] = (
        {"served": args.model, "announced": model.announced} | {
            key: model.announced[key] for key in ("weights_sha256",)
            if key in model.announced} if isinstance(model, RemoteModel) else
        {"checkpoint": str(Path(args.model).resolve()),
         "weights_sha256": read_config(args.model)["weights_sha256"]})
    data = source | {"dataset": str(args.data.resolve())} | result.to_json()
    text = json.dumps(data, indent=2, allow_nan=False) + "\n"
    out.parent.mkdir(parents=True, exist_ok=True)
    atomic_write(out, lambda temporary: temporary.write_text(text, encoding="utf-8"))
    print(f"evaluation: {out}")
    return 0


def run_show_attention(args: argparse.Namespace) -> int:
    """``gva show attention``: one PNG per sample, a row per condition for top-down models."""
    model, dataset = _model_and_dataset(args)
    meta, count = dataset.metadata, min(args.count, len(dataset))
    images = dataset.images[:count]  # (n, H, W, 3)
    read_as = model.condition_rows([dataset.condition(i) for i in range(len(dataset))],
                                   dataset.conditions)  # what the model reads each condition as
    shown = range(count)
    own = model.predict_samples(dataset, shown, read_as[:count])
    if own[0].attention_px.shape[0] == 0:
        raise PerceptionError(f"model {model.name} ({args.model}) predicts no attention "
                              "points, so there is nothing to draw (conv-ae and fcn have none; "
                              "kqv, keypoint and dsae have them)")
    choices = meta.condition_choices
    names = dataset.condition_names()
    # One row per value: its one-hot vector, or the first sentence (picture) that names it.
    asked = [names.index(value) for value in choices if value in names]
    by_condition = [model.predict_samples(dataset, shown, np.repeat(read_as[j:j + 1], count,
                                                                    axis=0))
                    for j in asked]  # [C][n]
    if choices:
        print("rows: " + ", ".join(f"{c} = {_asked(dataset, names, j)}"
                                   for c, j in enumerate(asked))
              + " (the sample's own condition is the white number)")
    if isinstance(model, KqvModel) and (read := model.read_sentences(read_as[asked])) is not None:
        for c, weights in enumerate(read):
            print(f"kqv reads row {c}'s sentence as " + ", ".join(
                f"{choice} {w:.2f}" for choice, w in zip(choices, weights, strict=True)))
    print("dots: attention points, numbered by head; panels: each head's heatmap")
    for i in range(count):
        if choices:
            chosen = next((c for c, j in enumerate(asked) if names[j] == names[i]), -1)
            rows = [AttentionRow(p[i].attention_px, p[i].heatmaps, label=c,
                                 highlighted=c == chosen) for c, p in enumerate(by_condition)]
        else:
            rows = [AttentionRow(own[i].attention_px, own[i].heatmaps)]
        text = meta.condition_kind is ConditionKind.TEXT
        caption = [f"{c}: {_asked(dataset, names, j)}" for c, j in enumerate(asked)] if text \
            else []
        path = write_png(args.out / f"attention-{i:03d}.png",
                         attention_figure(images[i], rows, args.scale, caption))
        condition = f", condition {_asked(dataset, names, i)}" if choices else ""
        print(f"sample {i}{condition}: {path}")
        for line in _sample_lines(own[i], dataset.labels[i]):
            print(f"  {line}")
    return 0


def _asked(dataset: Dataset, names: Sequence[str | None], index: int) -> str:
    """Sample ``index``'s condition for people: its value, and the sentence that asked for it.

    ``names`` is the dataset's :meth:`~perception.learning.data.Dataset.condition_names`,
    computed once by the caller.
    """
    given = dataset.condition(index)
    return f'{names[index]} ("{given.value}")' if given.kind is ConditionKind.TEXT \
        else str(names[index])


def _served_and_dataset(args: argparse.Namespace) -> tuple[RemoteModel, Dataset]:
    """The served model ``--model`` and the dataset ``--data``, checked as a checkpoint's."""
    model = RemoteModel(args.model)  # a served checkpoint announces what it was trained for
    return model, _fitting_dataset(args.data, model.spec, f"the model served at {args.model}",
                                   str(model.announced.get("name")))


def _model_and_dataset(args: argparse.Namespace) -> tuple[LearnableModel, Dataset]:
    """The checkpoint ``--model`` and the dataset ``--data``, checked to fit each other."""
    model = load_model(Path(args.model), args.model_class)
    return model, _fitting_dataset(args.data, model.spec, f"the checkpoint {args.model}",
                                   model.name)


def _fitting_dataset(path: Path, spec: ModelSpec | None, model: str, name: str) -> Dataset:
    """The dataset at ``path``, refused unless it has samples and fits ``spec`` (if any).

    ``model``: the model as the message names it (``the checkpoint FOLDER``); ``name``: its name.
    """
    dataset = load_dataset(path)
    if spec is not None:
        try:
            spec.check_dataset(dataset)
        except InvalidInputError as error:
            raise PerceptionError(f"dataset {path} does not fit {model} ({name}, trained on "
                                  f"{spec.task}): {error.value}") from error
    if len(dataset) == 0:
        raise InvalidInputError("--data", str(path), "a dataset with samples; it has none")
    return dataset


def target_names(dataset: Dataset) -> list[str | None]:
    """Per target index, the object type it is in every sample; None where it varies."""
    names: list[str | None] = []
    types = dataset.target_types()  # (N, q)
    for k in range(dataset.metadata.targets):
        seen = {row[k] for row in types}
        names.append(seen.pop() if len(seen) == 1 else None)
    return names


def _target(k: int, names: Sequence[str | None]) -> str:
    return f"{k} ({names[k]})" if names[k] else str(k)


def _sample_lines(prediction: Prediction, labels: np.ndarray) -> list[str]:
    """Predicted and true position of each target, then the attention points, as text."""
    lines = []
    for k, target in enumerate(prediction.targets):
        truth = labels[k, :3].astype(np.float64)
        error_cm = float(np.linalg.norm(target.position_m - truth)) * 100
        lines.append(f"target {k}: predicted {_xyz(target.position_m)} m, true {_xyz(truth)} m,"
                     f" {error_cm:.1f} cm apart")
    points = ", ".join(f"{k} ({u:.1f}, {v:.1f})" for k, (u, v) in
                       enumerate(prediction.attention_px))
    lines.append(f"attention points (u, v) px: {points}")
    return lines


def _xyz(position: np.ndarray) -> str:
    return "(" + ", ".join(f"{value:.3f}" for value in position) + ")"
