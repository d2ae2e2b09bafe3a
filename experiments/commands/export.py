"""``gva export`` and ``gva import``: a dataset file as a LeRobot v3.0 folder, and back.

    gva export --format lerobot runs/yumi-multiple-20.gva runs/yumi-multiple-20-lerobot
    gva import runs/yumi-multiple-20-lerobot runs/yumi-multiple-20-again.gva

The folder loads in LeRobot (``LeRobotDataset("local/name", root=FOLDER)``); importing it gives
back the same dataset, byte for byte (:mod:`perception.learning.lerobot_format`,
``docs/lerobot.md``).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from perception.interface import InvalidInputError
from perception.learning.data import Dataset

FORMATS = ("lerobot",)  # what --format takes


def add_export_options(parser: argparse.ArgumentParser) -> None:
    """The options of ``gva export``."""
    parser.add_argument("--format", required=True, metavar="FORMAT",
                        help=f"the folder's format: {', '.join(FORMATS)}")
    parser.add_argument("dataset", type=Path, metavar="DATASET",
                        help="a dataset file of gva collect (.gva)")
    parser.add_argument("out", type=Path, metavar="OUT",
                        help="the folder to write (must not exist, or be empty)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.set_defaults(run=run_export)


def add_import_options(parser: argparse.ArgumentParser) -> None:
    """The options of ``gva import``."""
    parser.add_argument("folder", type=Path, metavar="FOLDER",
                        help="a LeRobot v3.0 folder gva export wrote")
    parser.add_argument("out", type=Path, metavar="OUT",
                        help="the dataset file to write (.gva, must not exist)")
    parser.set_defaults(run=run_import)


def run_export(args: argparse.Namespace) -> int:
    """Checks the arguments, exports the dataset and says what it wrote; the exit status (0)."""
    if args.format not in FORMATS:
        raise InvalidInputError("--format", args.format, f"one of {', '.join(FORMATS)}")
    _check_gva("DATASET", args.dataset)
    if not args.dataset.is_file():
        raise InvalidInputError("DATASET", str(args.dataset), "an existing .gva dataset file")
    out: Path = args.out
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise InvalidInputError("OUT", str(out), "a folder that does not exist or is empty")
    from perception.learning.lerobot_format import export_lerobot  # pyarrow: only here

    result = export_lerobot(args.dataset, out, progress=not args.no_progress)
    print(f"{result.frames} samples as {result.episodes} LeRobot episodes, "
          f"{result.bytes_written / 1e6:.2f} MB in {result.seconds:.1f} s")
    print(f"folder: {result.folder}")
    return 0


def run_import(args: argparse.Namespace) -> int:
    """Checks the arguments, imports the folder, writes the dataset file; the exit status (0)."""
    if not args.folder.is_dir():
        raise InvalidInputError("FOLDER", str(args.folder), "a folder gva export wrote")
    _check_gva("OUT", args.out)
    if args.out.exists():
        raise InvalidInputError("OUT", str(args.out), "a .gva path that does not exist yet")
    from perception.learning.dataset_file import save_dataset
    from perception.learning.lerobot_format import import_lerobot  # pyarrow: only here

    dataset: Dataset = import_lerobot(args.folder)
    save_dataset(dataset, args.out)
    meta = dataset.metadata
    print(f"{meta.size} samples of {meta.scene} / {meta.task} (seed {meta.seed}), "
          "the same as exported (checksum)")
    print(f"dataset: {args.out}")
    return 0


def _check_gva(name: str, path: Path) -> None:
    """An error naming ``name`` unless ``path`` ends in .gva."""
    if path.suffix != ".gva":
        raise InvalidInputError(name, str(path), "a dataset file named *.gva")
