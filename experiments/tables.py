"""What both tables use (``gva reproduce sim``, Table II, and ``gva reproduce real``, Table III).

- the paper's tasks and models, their titles in the reports, and a model's hyper-parameters
  as a run folder records them (:func:`model_config`);
- run folders: JSON and text files written atomically, the error file of a job that raised
  (:func:`guarded`), the refusal of files made with other settings
  (:func:`refuse_other_settings`), the datasets a run reuses (:func:`dataset_present`);
- settings checks (:func:`check_choices`, :func:`check_counts`);
- the one progress bar of a run (:func:`cost_bar`) and what a run did (:class:`RunReport`).
"""

from __future__ import annotations

import json
import sys
import traceback
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Generic, Protocol, TypeVar

from tqdm import tqdm

from harness.run_folder import differences, json_form
from perception.files import atomic_write
from perception.learning.dataset_file import read_metadata
from perception.model_config_file import ModelConfigFile
from perception.registry import MODELS as REGISTERED
from perception.registry import PRESETS, trainable
from robots import get_robot
from sim.errors import InvalidInputError, RunFolderError
from sim.tasks.scene_sampling import SeedStream
from sim.tasks.scene_specs import scene_camera
from sim.tasks.task_sensor import seen_in_scene
from sim.tasks.task_toml import load_task
from sim.trials.collector import APPROACH_MASKED_KEY, CollectSettings
from sim.trials.trial_settings import task_identity
from sim.world.head_camera import CameraConfig, camera_config

MODELS = ("kqv", "keypoint-16", "keypoint-min", "dsae-16", "conv-ae", "fcn")
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
    return "kqv" if model == "kqv-paper" else model if model in MODELS else None


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
    cls, preset = trainable(model)
    config = asdict(cls.config_class(**{**preset, **(settings or {})}, seed=seed))
    since: Mapping[str, Any] = getattr(cls.config_class, "SINCE", {})
    return {key: value for key, value in config.items()
            if key not in since or value != since[key]}


def model_config_file(files: Sequence[ModelConfigFile], model: str) -> ModelConfigFile | None:
    """The file of ``files`` (``--model-config``, at most one per model) for ``model``, if any."""
    return next((file for file in files if file.model == model), None)


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


# files of a run folder


def write_json(path: Path, data: Any) -> None:
    """Writes ``data`` as indented JSON, atomically (parents created)."""
    write_text(path, json.dumps(data, indent=2, allow_nan=False) + "\n")


def write_text(path: Path, text: str) -> None:
    """Writes ``text`` atomically (parents created)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write(path, lambda temporary: temporary.write_text(text, encoding="utf-8"))


def read_json(path: Path) -> Any:
    """The JSON in ``path``; a damaged file is a :class:`RunFolderError` naming it."""
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as error:
        raise RunFolderError(f"{path} is damaged ({error}); remove it to compute it again"
                             ) from None


Result = TypeVar("Result")


@dataclass(frozen=True)
class Failed:
    """A job that raised: ``message`` is ``"Type: message"``, as its error file says."""

    message: str


def guarded(work: Callable[[], Result], error_path: Path, record: Mapping[str, Any],
            extra: Mapping[str, Any] | None = None) -> Result | Failed:
    """Runs ``work``: its result, or :class:`Failed` with the exception written to a file.

    The error file ``error_path`` holds ``record``, then ``error`` and ``traceback``, then
    ``extra``; the run goes on with the other jobs. When ``work`` succeeds, the error file an
    earlier try left is removed.
    """
    try:
        result = work()
    except Exception as error:  # one job's failure is recorded; the others go on
        message = f"{type(error).__name__}: {error}"
        write_json(error_path, {**record, "error": message,
                                "traceback": traceback.format_exc(), **(extra or {})})
        return Failed(message)
    error_path.unlink(missing_ok=True)
    return result


def refuse_other_settings(identities: Iterable[tuple[str, Any, Any]], what: str) -> None:
    """Raises unless every file was made with the settings asked now.

    Args:
        identities: Per file: its name as shown, the identity it stores, the identity asked.
        what: What the files are, e.g. ``"checkpoint(s)"``.

    Raises:
        RunFolderError: Some differ; the message lists them and what differs.

    """
    stale = [f"{name} ({differences(stored, asked)})" for name, stored, asked in identities
             if stored != asked]
    if stale:
        raise RunFolderError(
            f"{len(stale)} {what} made with other settings, stored vs now: "
            f"{'; '.join(stale[:3])}{' ...' if len(stale) > 3 else ''}; remove them to "
            "compute them again with the current code, or use another --out")


def dataset_path(out: Path, task: str, stream: SeedStream, size: int, seed: int) -> Path:
    """Where a training (TRAIN) or test (TEST) dataset of a run folder lives."""
    return out / "datasets" / f"{task}-{stream.name.lower()}-{size}-s{seed}.gva"


def dataset_present(path: Path, scene: str, task: str, size: int, seed: int,
                    stream: SeedStream, approach_hz: float | None = None,
                    robot: str = "yumi") -> bool:
    """Whether ``path`` holds the dataset asked for; refuses a file that holds another.

    ``task`` is a built-in task's name or a task file's path. Compared: scene, task name,
    size (in scenes: a yumi demonstration has an image per pick, a training scene of a task
    with a condition a sample per condition value), seed, seed stream, whether each scene is
    asked every condition
    (:class:`sim.trials.collector.CollectSettings` ``every_condition``, at its default for the
    stream), the task's definition (a task whose TOML changed since is another dataset), the
    scene's camera (other images; in the yumi scene, ``robot``'s), the robot where it is not
    the YuMi, and the approach images' rate (``approach_hz``, if any) and whether the arm is
    masked out of them (datasets from before the mask have it in view: another dataset).

    Raises:
        RunFolderError: ``path`` holds another dataset; the message names what differs.

    """
    if not path.exists():
        return False
    meta = read_metadata(path)
    definition = seen_in_scene(load_task(task), scene)  # as collect sees it: its sensor named
    asked = json_form({"scene": scene, "task": definition.name, "size": size, "seed": seed,
                       "stream": stream.name.lower(),
                       "every_condition": CollectSettings(scene, task, size, seed,
                                                          stream).asks_every_condition,
                       "definition": task_identity(definition),
                       "camera": asdict(scene_camera(scene) if scene != "yumi" else
                                        camera_config(get_robot(robot)))}
                      | ({} if approach_hz is None else {"approach_hz": approach_hz,
                                                         APPROACH_MASKED_KEY: True})
                      | ({} if robot == "yumi" else {"robot": robot}))
    scenes = meta.extra.get("scenes", meta.size)  # a scene may give several samples
    found = {"scene": meta.scene, "task": meta.task, "size": scenes, "seed": meta.seed,
             "stream": meta.extra.get("stream"),
             "every_condition": meta.extra.get("every_condition", False),
             "definition": meta.extra.get("task"),
             "camera": json_form(asdict(CameraConfig.from_json(meta.camera)))} | (
                 {} if "approach_hz" not in meta.extra else
                 {"approach_hz": meta.extra["approach_hz"],
                  APPROACH_MASKED_KEY: meta.extra.get(APPROACH_MASKED_KEY, False)}) | (
                 {} if "robot" not in meta.extra else {"robot": meta.extra["robot"]})
    if found != asked:
        raise RunFolderError(f"{path} is not the dataset this run needs "
                             f"({differences(found, asked)}, stored vs asked); remove it to "
                             "collect it again")
    return True


# progress and summaries


def cost_bar(total: float, description: str, progress: bool) -> tqdm:
    """A bar over ``total`` estimated cost: percent done, elapsed, time left and a postfix.

    Measured in cost rather than in jobs, its time left stays honest while the long jobs,
    which run first, are still going.
    """
    return tqdm(total=total, disable=not progress or total <= 0, desc=description,
                file=sys.stderr,
                bar_format="{desc}: {percentage:3.0f}%|{bar}| [{elapsed}<{remaining}{postfix}]")


def duration(seconds: float) -> str:
    """``1 h 02 min`` or ``3 min 07 s``."""
    minutes, second = divmod(round(seconds), 60)
    hours, minute = divmod(minutes, 60)
    return f"{hours} h {minute:02d} min" if hours else f"{minute} min {second:02d} s"


class JobResult(Protocol):
    """A finished job, as a :class:`RunReport` counts it."""

    @property
    def failure(self) -> str | None:
        """None, or ``"Type: message"`` of the exception the job raised."""


Outcome = TypeVar("Outcome", bound=JobResult)
Skipped = TypeVar("Skipped")


@dataclass(frozen=True)
class RunReport(Generic[Outcome, Skipped]):
    """What a run of either table did: jobs computed and skipped, failures, outputs.

    ``wall_time_s`` covers the jobs, not drawing the reports after.
    """

    computed: tuple[Outcome, ...]
    skipped: tuple[Skipped, ...]  # finished earlier
    failed: tuple[dict[str, Any], ...]  # every failure the folder records, with its "error"
    wall_time_s: float
    outputs: tuple[Path, ...] = ()
    notes: tuple[str, ...] = ()
    table: str = ""  # a table to print with the summary (Table III's successes)

    def summary_lines(self, done: str, name: Callable[[dict[str, Any]], str]) -> list[str]:
        """Counts and wall time, then each failure (named by ``name``), then the notes."""
        failed_now = sum(outcome.failure is not None for outcome in self.computed)
        lines = [f"{len(self.computed)} {done} ({failed_now} failed), {len(self.skipped)} "
                 f"finished earlier and skipped; wall time {self.wall_time_s:.0f} s"]
        lines += [f"  FAILED {name(record)}: {record['error']}" for record in self.failed]
        return lines + [f"  note: {note}" for note in self.notes]
