"""Variants: one task under another appearance, as a fragment of a task file laid over it.

A variant is a TOML file of task-file tables (``[objects] palette``, ``[lighting]``,
``[table]``, ``[camera]`` mount keys, ``[distractors]``, ``[appearance]``) that
:func:`with_variant` lays over a task: its keys replace the task's, except
``distractors.types``, which join the task's own. The built-in variants
(``sim/tasks/variants/*.toml``) are the rows of a variant table: ``dark`` and ``block`` (the
paper's robustness rows), one per appearance condition (``palette``, ``textures``, ``light``,
``table``, ``mount``, ``colour-twins``, ``shape-twins``), ``varied`` with every one on, and
``varied-held-out`` (the train half for demonstrations, the test half for trials).

The varied task is named ``<task>+<variant>`` and keeps everything else of the task: its
scenes' objects, poses, targets and conditions are the task's (the look has its own stream).
"""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

from sim.errors import InvalidInputError
from sim.tasks.task_spec import TaskSpec
from sim.tasks.task_toml import load_task, task_from_data, task_to_toml
from sim.tasks.toml_file import read_toml_file

VARIANT_FILES = Path(__file__).resolve().parent / "variants"
MAX_VARIANT_FILE_BYTES = 16 * 1024
"""A variant file is a few hundred bytes; a bigger file is refused unread."""
VARIANT_TITLES = {
    "dark": "darker light (brightness 0.5)", "block": "+ block distractor",
    "palette": "household colourways", "textures": "printed textures",
    "light": "any lamp (2700-6500 K)", "table": "other tables",
    "mount": "camera re-mounted (15 mm, 2 deg)", "colour-twins": "+ colour twin",
    "shape-twins": "+ shape twins", "varied": "every look varied",
    "varied-held-out": "every look varied, held out"}
"""How a report names each built-in variant's row; a variant file is named by its stem."""
VARIANT_TABLES = {"objects": {"palette", "textures"}, "lighting": None, "table": None,
                  "camera": {"mount_offset_mm", "mount_offset_deg"}, "distractors": None,
                  "appearance": None}
"""What a variant may set: these tables (None: any key the task file takes there)."""


def builtin_variants() -> tuple[str, ...]:
    """Names of the variants that ship with gva (``sim/tasks/variants/*.toml``)."""
    return tuple(sorted(p.stem for p in VARIANT_FILES.glob("*.toml")))


def read_variant(name_or_path: str | Path) -> tuple[str, dict[str, Any], Path]:
    """A built-in variant by name, or a variant file by path: its name, tables and folder."""
    text = str(name_or_path)
    path = VARIANT_FILES / f"{text}.toml"
    if not path.is_file():
        path = Path(text)
        if not (text.endswith(".toml") and path.is_file()):
            raise InvalidInputError("variant", text, f"one of {', '.join(builtin_variants())}, "
                                    "or the path of a variant .toml file")
        if path.stem in builtin_variants() and path.resolve().parent != VARIANT_FILES:
            # a variant is named by its file's stem in folders and reports: this one would be
            # labelled as the built-in variant it is not
            raise InvalidInputError("variant", text, "a variant file whose name is not a "
                                    f"built-in variant's ({path.stem} is one): rename it")
    where = f"variant file {path.name}"
    tables = read_toml_file(path, where, MAX_VARIANT_FILE_BYTES, "a variant").tables
    for table, value in tables.items():
        if table not in VARIANT_TABLES or not isinstance(value, dict):
            raise InvalidInputError(f"{where}: {table}", value, "a table among "
                                    f"{', '.join(VARIANT_TABLES)}")
        allowed = VARIANT_TABLES[table]
        unknown = [] if allowed is None else sorted(set(value) - allowed)
        if allowed is not None and unknown:
            raise InvalidInputError(f"{where}: {table}.{unknown[0]}", value[unknown[0]],
                                    f"a key a variant sets there: {', '.join(sorted(allowed))}")
    return path.stem, tables, path.resolve().parent


def with_variant(task: TaskSpec, variant: str | Path) -> TaskSpec:
    """``task`` under ``variant``, named ``<task>+<variant>``; a bad key names the variant file.

    Raises:
        InvalidInputError: The variant is unknown or malformed, or the varied task is not a
            valid task (the message names the field as the task file's check does).

    """
    name, tables, folder = read_variant(variant)
    data = tomllib.loads(task_to_toml(task))
    for table, keys in tables.items():
        merged = data.setdefault(table, {})
        for key, value in keys.items():
            if table == "distractors" and key == "types":
                if not isinstance(value, list) or not all(isinstance(t, str) for t in value):
                    raise InvalidInputError(f"variant file {name}: distractors.types", value,
                                            "a list of object type names, e.g. [\"block\"]")
                merged[key] = [*merged.get(key, []), *(t for t in value
                                                       if t not in merged.get(key, []))]
            else:
                merged[key] = value
    data["name"] = f"{task.name}+{name}"
    return task_from_data(data, f"{task.source} + variant {name}", folder)


def variant_title(variant: str | Path) -> str:
    """A variant's row title in reports."""
    return VARIANT_TITLES.get(str(variant), Path(variant).stem)


def load_task_variant(task: str | Path, variant: str | Path | None) -> TaskSpec:
    """A task by name or file, under ``variant`` where one is given (``--task``, ``--variant``)."""
    loaded = load_task(task)
    return loaded if variant is None else with_variant(loaded, variant)


def variant_file(variant: str | Path) -> Path:
    """The file a variant is read from (a run's provenance names it)."""
    builtin = VARIANT_FILES / f"{variant}.toml"
    return builtin if builtin.is_file() else Path(variant)
