"""Where a benchmark's or a study's record goes, and how it is written.

Every script of ``benchmarks/`` and ``studies/`` ends the same way: a JSON record, by default
``benchmarks/results/<name>.json`` (relative to the folder the script is run from), written
by ``json.dumps`` with an indent (2; 1 where a script's records always had 1) and a trailing
newline. That ending lives here once. Scripts import it as
a sibling (``from results_file import ...``: running ``python benchmarks/X.py`` puts
``benchmarks/`` on the path); a study puts ``benchmarks/`` on the path first.

The writer refuses NaN and infinity: ``json.dumps`` would write them as ``NaN`` and
``Infinity``, which are not JSON, and no committed record holds one. The file is written next
to its target and renamed onto it, so a run stopped while writing leaves the old record whole.
"""

from __future__ import annotations

import argparse
import json
import math
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

RESULTS = Path("benchmarks/results")
"""The folder records go to unless ``--out`` names another; relative to the working folder."""


def record_path(name: str) -> Path:
    """The default record of the benchmark ``name``: ``benchmarks/results/<name>.json``."""
    return RESULTS / f"{name}.json"


def add_out_option(parser: argparse.ArgumentParser, name: str, *, flag: str = "--out",
                   help: str | None = None) -> None:
    """Adds ``flag`` (a path, default :func:`record_path` of ``name``): where the record goes."""
    parser.add_argument(flag, type=Path, default=record_path(name), help=help)


def _first_non_finite(value: Any, where: str = "the record") -> str | None:
    """Where in ``value`` (parsed JSON) the first NaN or infinity sits, as a readable path."""
    if isinstance(value, float) and not math.isfinite(value):
        return f"{where} ({value})"
    if isinstance(value, dict):
        items = ((f"{where}[{key!r}]", item) for key, item in value.items())
    elif isinstance(value, list):
        items = ((f"{where}[{index}]", item) for index, item in enumerate(value))
    else:
        return None
    for inner, item in items:
        found = _first_non_finite(item, inner)
        if found is not None:
            return found
    return None


def record_text(record: Any, *, indent: int = 2,
                default: Callable[[Any], Any] | None = None) -> str:
    """``record`` as the records are written: ``json.dumps`` with ``indent``, then a newline.

    ``default`` converts what JSON has no form for, as ``json.dumps``'s ``default`` does.
    Raises ValueError naming the first NaN or infinity: JSON has no form for them.
    """
    try:
        text = json.dumps(record, indent=indent, default=default, allow_nan=False)
    except ValueError as error:
        lenient = json.dumps(record, indent=indent, default=default)  # raises what else failed
        where = _first_non_finite(json.loads(lenient))
        raise ValueError(f"{where} is not a finite number, and JSON has no form for NaN or "
                         "infinity; the record is not written") from error
    return text + "\n"


def write_record(path: Path, record: Any, *, indent: int = 2,
                 default: Callable[[Any], Any] | None = None, announce: bool = True) -> None:
    """Writes ``record`` to ``path`` as :func:`record_text` forms it, then prints ``wrote PATH``.

    The folder is made if missing. The text goes to a file beside ``path`` (beside the file a
    link points to), renamed onto it once complete. ``announce=False`` prints nothing, for a
    script that says where it wrote in a line of its own.
    """
    text = record_text(record, indent=indent, default=default)
    path.parent.mkdir(parents=True, exist_ok=True)
    target = Path(os.path.realpath(path))
    partial = target.with_name(f".{target.name}.{os.getpid()}.partial")
    try:
        with partial.open("x", encoding="utf-8") as file:
            file.write(text)
        os.replace(partial, target)
    except BaseException:
        partial.unlink(missing_ok=True)
        raise
    if announce:
        print(f"wrote {path}")
