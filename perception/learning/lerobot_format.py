"""gva datasets as LeRobotDataset v3.0 folders and back, without the ``lerobot`` package.

:func:`export_lerobot` writes a ``.gva`` dataset as a folder LeRobot loads
(``LeRobotDataset(repo_id, root=FOLDER)``); :func:`import_lerobot` reads such a folder back into
the same :class:`~perception.learning.data.Dataset`, array for array, byte for byte::

    meta/info.json                           codebase_version "v3.0", fps, features, totals
    meta/stats.json                          min, max, mean, std, count, q01 ... q99 per feature
    meta/tasks.parquet                       one row per task string (its index: task_index)
    meta/episodes/chunk-000/file-000.parquet one row per episode: ranges, tasks, stats/...
    meta/gva.json                            what has no LeRobot column: metadata, scene records
    data/chunk-000/file-000.parquet          one row per sample (frame)

One episode per scene: the samples that share a scene record's ``"index"``, in dataset order (a
``multiple`` demonstration's image before each pick; one sample per condition value). Images
are PNG bytes in the parquet file (LeRobot's ``"image"`` dtype): lossless, no video codec.
``docs/lerobot.md`` maps every column to what it came from.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import shutil
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image
from tqdm import tqdm

from perception.files import FileError
from perception.interface import InvalidInputError
from perception.learning.data import Dataset, DatasetMetadata
from perception.learning.dataset_file import (
    contents_sha256,
    load_dataset,
    metadata_from_json,
    metadata_to_json,
)
from perception.learning.lerobot_features import (
    CONDITION_KEY,
    DEPTH_KEY,
    FPS,
    IMAGE_KEY,
    PRESENT_KEY,
    STATE_KEY,
    all_stats,
    info_features,
)

try:
    import pyarrow as pa
    import pyarrow.parquet as pq
except ImportError as missing:  # an optional extra: say which
    raise ImportError("LeRobot folders need pyarrow: pip install 'gva[lerobot]'") from missing

CODEBASE_VERSION = "v3.0"  # LeRobot's dataset format, checked by its loader
CHUNKS_SIZE = 1000  # LeRobot's defaults: files per chunk folder, MB per data / video file
DATA_FILES_SIZE_IN_MB = 100
VIDEO_FILES_SIZE_IN_MB = 200
GVA_PATH = "meta/gva.json"
GVA_FORMAT = "gva-lerobot/1"
_DATA_PATH = "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
_EPISODES_PATH = "meta/episodes/chunk-000/file-000.parquet"
_IMAGE_TYPE = pa.struct([("bytes", pa.binary()), ("path", pa.string())])  # HF datasets' Image
# LeRobot reads tasks.parquet with pandas and looks tasks up by the frame's index: the
# task strings. This metadata makes the "task" column that index, as pandas would write it.
_TASKS_PANDAS = json.dumps({
    "index_columns": ["task"], "column_indexes": [], "pandas_version": "2.0.0",
    "columns": [{"name": name, "field_name": name, "pandas_type": kind, "numpy_type": numpy,
                 "metadata": None} for name, kind, numpy in (("task_index", "int64", "int64"),
                                                             ("task", "unicode", "object"))]})
_GVA_KEYS = {"metadata", "scenes", "condition_size", "contents_sha256"}
class LeRobotFolderError(FileError):
    """A folder gva cannot import: not LeRobot v3.0, not exported by gva, or changed since."""

    kind = "LeRobot folder"


@dataclass(frozen=True)
class ExportResult:
    """What :func:`export_lerobot` wrote: the folder, its episodes and frames, bytes and time."""

    folder: Path
    episodes: int
    frames: int
    bytes_written: int
    seconds: float


def export_lerobot(dataset: Dataset | str | Path, out_dir: str | Path,
                   progress: bool = False) -> ExportResult:
    """Writes ``dataset`` (or the ``.gva`` file at that path) as a LeRobot v3.0 folder.

    ``out_dir`` must not exist or be empty; the folder appears under its name only once
    complete (written beside it, then renamed).
    """
    start_s = time.perf_counter()
    data = dataset if isinstance(dataset, Dataset) else load_dataset(dataset)
    out = Path(out_dir)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise InvalidInputError("out_dir", str(out), "a folder that does not exist or is empty")
    if len(data) == 0:
        raise InvalidInputError("dataset", "0 samples", "a dataset with at least one sample")
    out.parent.mkdir(parents=True, exist_ok=True)
    partial = Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".partial", dir=out.parent))
    try:
        episodes = _write_folder(data, partial, progress)
        written = sum(p.stat().st_size for p in partial.rglob("*") if p.is_file())
        if out.exists():
            out.rmdir()
        os.replace(partial, out)
    finally:
        shutil.rmtree(partial, ignore_errors=True)
    return ExportResult(out, episodes, len(data), written, time.perf_counter() - start_s)


def import_lerobot(folder: str | Path) -> Dataset:
    """The dataset a folder of :func:`export_lerobot` holds, checked against its checksum."""
    root = Path(folder)
    info, gva = (_read_json(root, name) for name in ("meta/info.json", GVA_PATH))
    if info.get("codebase_version") != CODEBASE_VERSION:
        raise LeRobotFolderError(root, f"codebase_version is {info.get('codebase_version')!r}; "
                                 f"gva reads {CODEBASE_VERSION!r}")
    if gva.get("format") != GVA_FORMAT:
        raise LeRobotFolderError(root, f"{GVA_PATH} format is {gva.get('format')!r}; "
                                 f"gva reads {GVA_FORMAT!r}")
    if missing_keys := sorted(_GVA_KEYS - set(gva)):
        raise LeRobotFolderError(root, f"{GVA_PATH} lacks {', '.join(missing_keys)}")
    if "files_sha256" in gva:  # exported since issue 63: every file as written, none added
        _check_files(root, gva["files_sha256"])
    metadata = _metadata(root, gva["metadata"])
    try:
        result = _dataset_of(root, gva, metadata)
    except LeRobotFolderError:
        raise
    except (pa.ArrowException, OSError, ValueError, TypeError, KeyError, IndexError) as error:
        said = " ".join(str(error).split())[:200]  # a library's message, kept to one line
        raise LeRobotFolderError(root, f"data cannot be read as gva export wrote it "
                                 f"({type(error).__name__}: {said})") from error
    if contents_sha256(result) != gva["contents_sha256"]:
        raise LeRobotFolderError(root, "contents do not match the checksum in meta/gva.json: "
                                 "changed after export")
    return result


def _dataset_of(root: Path, gva: dict[str, Any], metadata: DatasetMetadata) -> Dataset:
    """The dataset the folder's data files hold (checked by the caller against its checksum).

    A file a library cannot read (a damaged parquet file or PNG, a column of another type)
    raises that library's error; :func:`import_lerobot` names the folder in one line.
    """
    paths = sorted(root.glob("data/*/*.parquet"))
    if not paths:
        raise LeRobotFolderError(root, "has no data/chunk-*/file-*.parquet")
    table = pa.concat_tables([pq.read_table(path) for path in paths])
    columns = [IMAGE_KEY, "action", "index"] + ([CONDITION_KEY] if gva["condition_size"] else [])
    columns += [key for key in (gva.get("depth"), gva.get("state")) if key]
    if missing := [name for name in columns if name not in table.column_names]:
        raise LeRobotFolderError(root, f"data lacks columns {', '.join(missing)}")
    order = np.argsort(table.column("index").to_numpy(), kind="stable")
    table = table.take(pa.array(order))
    if not np.array_equal(table.column("index").to_numpy(), np.arange(metadata.size)):
        raise LeRobotFolderError(root, f"data indices are not 0 .. {metadata.size - 1}, one each")
    n = metadata.size
    images = np.stack([_png_pixels(cell["bytes"]) for cell in table.column(IMAGE_KEY).to_pylist()])
    labels = _vectors(table, "action").reshape(n, metadata.targets, metadata.label_dim)
    conditions = (_vectors(table, CONDITION_KEY) if gva["condition_size"]
                  else np.zeros((n, 0), dtype=np.float32))
    h, w = metadata.image_height_px, metadata.image_width_px
    depths = (_vectors(table, DEPTH_KEY, nested=True).reshape(n, h, w)
              if gva.get("depth") else None)
    joints = _vectors(table, STATE_KEY) if gva.get("state") else None
    try:
        result = Dataset(metadata, images, conditions, labels, tuple(gva["scenes"]),
                         depths_m=depths, joint_positions=joints)
    except InvalidInputError as error:
        raise LeRobotFolderError(root, f"holds data a dataset cannot have: {error}") from error
    return result


def _files_sha256(root: Path) -> dict[str, str]:
    """Every file under ``root`` but meta/gva.json: its path (``/``-separated) -> SHA-256."""
    return {path.relative_to(root).as_posix(): hashlib.sha256(path.read_bytes()).hexdigest()
            for path in sorted(root.rglob("*")) if path.is_file()
            and path.relative_to(root).as_posix() != GVA_PATH}


def _check_files(root: Path, expected: Any) -> None:
    """Refuses a folder whose files differ from the export's: changed, missing or added.

    The contents checksum covers what gva reads back; this covers what LeRobot reads too
    (info.json's counts and shapes, the episodes and tasks tables, stats.json), so a folder
    changed after export is refused whichever file changed (docs/lerobot.md).
    """
    if not (isinstance(expected, dict) and all(isinstance(k, str) and isinstance(v, str)
                                               for k, v in expected.items())):
        raise LeRobotFolderError(root, f"{GVA_PATH} files_sha256 is not a table of path: SHA-256")
    found = _files_sha256(root)
    for path, digest in expected.items():
        if path not in found:
            raise LeRobotFolderError(root, f"lacks {path}, which the export wrote")
        if found[path] != digest:
            raise LeRobotFolderError(root, f"{path} changed after export (its SHA-256 differs "
                                     f"from the one in {GVA_PATH})")
    if added := sorted(set(found) - set(expected)):
        raise LeRobotFolderError(root, f"holds {added[0]}, which the export did not write")


def episode_bounds(dataset: Dataset) -> list[tuple[int, int]]:
    """Each episode's [start, stop) samples: runs of samples that share a scene, in order."""
    keys = dataset.scene_keys()
    starts = [0] + [n for n in range(1, len(keys)) if keys[n] != keys[n - 1]]
    return list(zip(starts, [*starts[1:], len(keys)], strict=True))


def frame_tasks(dataset: Dataset) -> list[str]:
    """Each sample's LeRobot task string: the task name, then what its condition names."""
    name = dataset.metadata.task
    return [name if value is None else f"{name}: {value}" for value in dataset.condition_names()]


def _write_folder(data: Dataset, root: Path, progress: bool) -> int:
    """Writes every file of the folder into ``root``; the number of episodes."""
    meta, n = data.metadata, len(data)
    bounds = episode_bounds(data)
    tasks = frame_tasks(data)
    task_names = list(dict.fromkeys(tasks))
    episode_of = np.repeat(np.arange(len(bounds)), [stop - start for start, stop in bounds])
    frame_of = np.concatenate([np.arange(stop - start) for start, stop in bounds])
    columns: dict[str, np.ndarray] = {
        "action": data.labels.reshape(n, -1),  # (N, q * D) float32
        PRESENT_KEY: data.target_present().astype(np.float32),  # (N, q)
        "timestamp": (frame_of / FPS).astype(np.float32),
        "frame_index": frame_of.astype(np.int64),
        "episode_index": episode_of.astype(np.int64),
        "index": np.arange(n, dtype=np.int64),
        "task_index": np.array([task_names.index(t) for t in tasks], dtype=np.int64),
    }
    if data.conditions.shape[1]:
        columns[CONDITION_KEY] = data.conditions  # (N, C) float32
    if data.joint_positions is not None:
        columns[STATE_KEY] = data.joint_positions  # (N, J) float32
    features = info_features(data)
    pngs = [_png_bytes(image) for image in tqdm(data.images, desc="export lerobot: images",
                                                unit="image", disable=not progress)]
    files, episodes = _write_data(root, columns, pngs, bounds, data.depths_m)
    stats_rows = [all_stats(columns, data.images[start:stop], _part(data.depths_m, start, stop))
                  for start, stop in bounds]
    for e, (start, stop) in enumerate(bounds):
        episodes[e] |= {"episode_index": e, "length": stop - start,
                        "tasks": list(dict.fromkeys(tasks[start:stop])),
                        "dataset_from_index": start, "dataset_to_index": stop,
                        "meta/episodes/chunk_index": 0, "meta/episodes/file_index": 0}
        episodes[e] |= {f"stats/{key}/{stat}": value
                        for key, stat_values in stats_rows[e].items()
                        for stat, value in stat_values.items()}
    (root / _EPISODES_PATH).parent.mkdir(parents=True)
    pq.write_table(pa.Table.from_pylist(episodes), root / _EPISODES_PATH)
    tasks_table = pa.table({"task_index": pa.array(range(len(task_names)), pa.int64()),
                            "task": pa.array(task_names, pa.string())})
    pq.write_table(tasks_table.replace_schema_metadata({"pandas": _TASKS_PANDAS}),
                   root / "meta/tasks.parquet")
    info = {"codebase_version": CODEBASE_VERSION,
            "robot_type": "abb_yumi" if meta.scene == "yumi" else None,
            "total_episodes": len(bounds), "total_frames": n, "total_tasks": len(task_names),
            "chunks_size": CHUNKS_SIZE, "data_files_size_in_mb": DATA_FILES_SIZE_IN_MB,
            "video_files_size_in_mb": VIDEO_FILES_SIZE_IN_MB, "fps": FPS,
            "splits": {"train": f"0:{len(bounds)}"},
            "data_path": _DATA_PATH, "video_path": None,
            "features": features}
    _write_json(root / "meta/info.json", info)
    _write_json(root / "meta/stats.json", all_stats(columns, data.images, data.depths_m))
    _write_json(root / GVA_PATH, {"files_sha256": _files_sha256(root)} | {
        "format": GVA_FORMAT, "metadata": metadata_to_json(meta), "scenes": list(data.scenes),
        "condition_size": int(data.conditions.shape[1]), "contents_sha256": contents_sha256(data),
        "data_files": files, "depth": DEPTH_KEY if data.depths_m is not None else None,
        "state": STATE_KEY if data.joint_positions is not None else None})
    return len(bounds)


def _write_data(root: Path, columns: dict[str, np.ndarray], pngs: list[bytes],
                bounds: list[tuple[int, int]], depths_m: np.ndarray | None
                ) -> tuple[list[str], list[dict[str, Any]]]:
    """Data files of whole episodes, each up to DATA_FILES_SIZE_IN_MB; their paths, rows."""
    limit_bytes = DATA_FILES_SIZE_IN_MB * 2**20
    frame_bytes = sum(column[0].nbytes for column in columns.values())  # besides its PNG
    frame_bytes += 0 if depths_m is None else depths_m[0].nbytes
    groups: list[list[int]] = [[]]
    size_bytes = 0
    for e, (start, stop) in enumerate(bounds):
        episode_bytes = sum(map(len, pngs[start:stop])) + frame_bytes * (stop - start)
        if groups[-1] and size_bytes + episode_bytes > limit_bytes:
            groups.append([])
            size_bytes = 0
        groups[-1].append(e)
        size_bytes += episode_bytes
    files, episodes = [], []
    for number, group in enumerate(groups):
        chunk, file = divmod(number, CHUNKS_SIZE)
        start, stop = bounds[group[0]][0], bounds[group[-1]][1]
        table = {IMAGE_KEY: pa.array([{"bytes": png, "path": None} for png in pngs[start:stop]],
                                     _IMAGE_TYPE)}
        for key, column in columns.items():
            part = column[start:stop].reshape(stop - start, -1)  # (n, D)
            # LeRobot reads a feature of shape (1,) as a scalar column, any other as a list
            table[key] = (pa.array(part[:, 0]) if part.shape[1] == 1 else
                          pa.FixedSizeListArray.from_arrays(pa.array(part.reshape(-1)),
                                                            part.shape[1]))
        if depths_m is not None:  # (n, H, W): rows of rows, as LeRobot's 2-D features read
            depth = depths_m[start:stop]
            rows = pa.FixedSizeListArray.from_arrays(pa.array(depth.reshape(-1)), depth.shape[2])
            table[DEPTH_KEY] = pa.FixedSizeListArray.from_arrays(rows, depth.shape[1])
        path = _DATA_PATH.format(chunk_index=chunk, file_index=file)
        (root / path).parent.mkdir(parents=True, exist_ok=True)
        pq.write_table(pa.table(table), root / path)
        files.append(path)
        episodes += [{"data/chunk_index": chunk, "data/file_index": file} for _ in group]
    return files, episodes


def _part(array: np.ndarray | None, start: int, stop: int) -> np.ndarray | None:
    return None if array is None else array[start:stop]


def _png_bytes(image: np.ndarray) -> bytes:
    """(H, W, 3) uint8 as PNG bytes: lossless, the same bytes for the same pixels."""
    buffer = io.BytesIO()
    Image.fromarray(image).save(buffer, format="PNG")
    return buffer.getvalue()


def _png_pixels(data: bytes) -> np.ndarray:
    """(H, W, 3) uint8 of PNG bytes."""
    with Image.open(io.BytesIO(data)) as image:
        return np.asarray(image.convert("RGB"), dtype=np.uint8)


def _vectors(table: pa.Table, key: str, nested: bool = False) -> np.ndarray:
    """(N, D) float32 of a fixed-size list column (of lists, ``nested``), or (N, 1) of a scalar."""
    column = table.column(key).combine_chunks()
    values = column.flatten() if pa.types.is_fixed_size_list(column.type) else column
    if nested:
        values = values.flatten()
    return np.asarray(values.to_numpy(), dtype=np.float32).reshape(len(column), -1)


def _metadata(root: Path, data: dict[str, Any]) -> DatasetMetadata:
    """The metadata of its JSON form, validated."""
    try:
        return metadata_from_json(data)
    except (InvalidInputError, KeyError, TypeError) as error:
        raise LeRobotFolderError(root, f"{GVA_PATH} metadata is not valid: {error}") from error


def _read_json(root: Path, name: str) -> dict[str, Any]:
    """A JSON object of the folder; an error naming the file if missing or damaged."""
    path = root / name
    if not path.is_file():
        raise LeRobotFolderError(root, f"has no {name}" + (
            "; gva imports folders it exported" if name == GVA_PATH else ""))
    try:
        value = json.loads(path.read_text())
    except ValueError as error:
        raise LeRobotFolderError(root, f"{name} is not JSON ({error})") from error
    if not isinstance(value, dict):
        raise LeRobotFolderError(root, f"{name} is not a JSON object")
    return value


def _write_json(path: Path, value: dict[str, Any]) -> None:
    """``value`` as indented JSON (LeRobot's own files are indented)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(value, indent=4, allow_nan=False) + "\n")
