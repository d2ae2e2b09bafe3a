"""LeRobot v3.0 export and import: the same dataset back, byte for byte; a layout LeRobot reads."""

from __future__ import annotations

import json
import re
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from perception.interface import PICTURE_PX, ConditionKind, InvalidInputError, LabelKind
from perception.labels import label_vector
from perception.learning import lerobot_features, lerobot_format
from perception.learning.data import Dataset, DatasetMetadata
from perception.learning.dataset_file import save_dataset
from perception.learning.lerobot_features import IMAGE_KEY
from perception.learning.lerobot_format import (
    LeRobotFolderError,
    export_lerobot,
    import_lerobot,
)

INFO_KEYS = {"codebase_version", "robot_type", "total_episodes", "total_frames", "total_tasks",
             "chunks_size", "data_files_size_in_mb", "video_files_size_in_mb", "fps", "splits",
             "data_path", "video_path", "features"}
STATS = {"min", "max", "mean", "std", "count", "q01", "q10", "q50", "q90", "q99"}


def rotations(rng: np.random.Generator, n: int) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(n, 3, 3)))
    q = q * np.sign(np.diagonal(r, axis1=1, axis2=2))[:, None, :]
    return q * np.linalg.det(q)[:, None, None]  # (n, 3, 3), det +1


def make(kind=LabelKind.GRASP_POSE, condition=ConditionKind.OBJECT_TYPE, keys=(0, 0, 0, 1, 1, 1),
         q=3, seed=0, depth_and_joints=False) -> Dataset:
    """A yumi-like dataset: samples of scene ``keys[n]``, later pick stages with targets taken."""
    rng = np.random.default_rng(seed)
    size, choices = len(keys), ("sponge", "mug") if condition is not ConditionKind.NONE else ()
    metadata = DatasetMetadata(
        scene="yumi", task="selected-type", size=size, seed=seed, image_height_px=12,
        image_width_px=10, label_kind=kind, targets=q, condition_kind=condition,
        condition_choices=choices, camera={"position_m": [0.09, 0.0, 0.52], "fov_deg": 58.0},
        extra={"task": {"name": "selected-type"}, "redrawn": [{"scene_index": 2}]}
        | ({"joint_names": ["j1", "j2", "gripper"]} if depth_and_joints else {}))
    named = rng.integers(len(choices), size=size) if choices else np.zeros(size, int)
    if condition is ConditionKind.OBJECT_TYPE:
        conditions = np.eye(len(choices), dtype=np.float32)[named]
    elif condition is ConditionKind.IMAGE:
        conditions = rng.random((size, PICTURE_PX * PICTURE_PX * 3), dtype=np.float32)
    else:
        conditions = np.zeros((size, 0), np.float32)
    stage = [sum(1 for k in keys[:n] if k == keys[n]) for n in range(size)]
    scenes = tuple({"index": int(keys[n]), "taken": list(range(min(stage[n], q)))} | (
        {"condition": {"kind": condition.value, "value": choices[named[n]]}} if choices else {})
        for n in range(size))
    position = rng.uniform(-0.3, 0.3, (size, q, 3))
    rotation = rotations(rng, size * q).reshape(size, q, 3, 3) \
        if kind is LabelKind.GRASP_POSE else None
    images = rng.integers(0, 256, (size, 12, 10, 3), dtype=np.uint8)
    depths = rng.uniform(0.3, 1.0, (size, 12, 10)).astype(np.float32)
    depths[:, 0, 0] = np.inf  # a pixel that sees nothing
    joints = rng.normal(size=(size, 3)).astype(np.float32)
    return Dataset(metadata, images, conditions, label_vector(position, rotation), scenes,
                   *((depths, joints) if depth_and_joints else ()))


CASES: dict[str, dict[str, Any]] = {
    "grasp-one-hot-stages": {},
    "position-no-condition": {"kind": LabelKind.POSITION, "condition": ConditionKind.NONE,
                              "keys": (0, 1, 2), "q": 1},
    "picture-condition": {"condition": ConditionKind.IMAGE, "keys": (0, 0, 1), "q": 1},
    "scenes-out-of-order": {"keys": (0, 1, 0, 2, 2)},
    "depth-and-joints": {"depth_and_joints": True},
}


@pytest.mark.parametrize("case", CASES)
def test_round_trip_is_byte_identical(tmp_path, case):
    original = make(**CASES[case])
    result = export_lerobot(original, tmp_path / "out")
    back = import_lerobot(tmp_path / "out")
    assert back == original
    assert back.metadata == original.metadata and back.scenes == original.scenes
    for name, a in original.tensors().items():
        b = getattr(back, name)
        assert a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()
    first = save_dataset(original, tmp_path / "a.gva").read_bytes()
    assert save_dataset(back, tmp_path / "b.gva").read_bytes() == first
    assert (result.frames, result.episodes) == (len(original), len(_runs(original)))
    files = [p for p in result.folder.rglob("*") if p.is_file()]
    assert result.bytes_written == sum(p.stat().st_size for p in files) > 0


def _runs(dataset: Dataset) -> list[int]:
    keys = dataset.scene_keys()
    return [n for n in range(len(keys)) if n == 0 or keys[n] != keys[n - 1]]


@pytest.mark.parametrize("case", CASES)
def test_the_folder_obeys_the_v3_layout(tmp_path, case):
    original = make(**CASES[case])
    root = export_lerobot(original, tmp_path / "out").folder
    info = json.loads((root / "meta/info.json").read_text())
    assert set(info) == INFO_KEYS and info["codebase_version"] == "v3.0"
    assert info["video_path"] is None and info["fps"] == lerobot_features.FPS
    episodes = pq.read_table(root / "meta/episodes/chunk-000/file-000.parquet").to_pylist()
    paths = {info["data_path"].format(chunk_index=e["data/chunk_index"],
                                      file_index=e["data/file_index"]) for e in episodes}
    assert paths == {p.relative_to(root).as_posix() for p in root.glob("data/*/*.parquet")}
    data = pa.concat_tables([pq.read_table(root / p) for p in sorted(paths)])
    assert info["total_frames"] == data.num_rows == len(original)
    assert info["total_episodes"] == len(episodes) == len(_runs(original))
    assert info["splits"] == {"train": f"0:{len(episodes)}"}
    for name, feature in info["features"].items():  # the loader casts each column to these
        kind = data.schema.field(name).type
        if feature["dtype"] == "image":
            assert kind == pa.struct([("bytes", pa.binary()), ("path", pa.string())])
            assert feature["shape"] == [12, 10, 3]
        elif feature["shape"] == [1]:
            assert kind == pa.from_numpy_dtype(np.dtype(feature["dtype"]))
        elif len(feature["shape"]) == 2:  # depth: rows of rows, as LeRobot's 2-D arrays
            assert pa.types.is_fixed_size_list(kind) and kind.list_size == feature["shape"][0]
            assert kind.value_type == pa.list_(pa.float32(), feature["shape"][1])
            assert feature["names"] == ["height", "width"]
        else:
            assert pa.types.is_fixed_size_list(kind)
            assert kind.list_size == feature["shape"][0] == len(feature["names"])
            assert kind.value_type == pa.from_numpy_dtype(np.dtype(feature["dtype"]))
    assert set(data.column_names) == set(info["features"])
    assert data.column("index").to_pylist() == list(range(len(original)))
    assert episodes[0]["dataset_from_index"] == 0
    assert episodes[-1]["dataset_to_index"] == info["total_frames"]
    tasks = pd.read_parquet(root / "meta/tasks.parquet")  # as LeRobot reads it: task -> index
    assert list(tasks["task_index"]) == list(range(info["total_tasks"]))
    frame_tasks = [tasks.iloc[i].name for i in data.column("task_index").to_pylist()]
    for e, episode in enumerate(episodes):
        start, stop = episode["dataset_from_index"], episode["dataset_to_index"]
        assert episode["episode_index"] == e and episode["length"] == stop - start > 0
        if e + 1 < len(episodes):
            assert episodes[e + 1]["dataset_from_index"] == stop
        rows = data.slice(start, stop - start)
        assert rows.column("episode_index").to_pylist() == [e] * (stop - start)
        assert rows.column("frame_index").to_pylist() == list(range(stop - start))
        assert episode["tasks"] == list(dict.fromkeys(frame_tasks[start:stop]))
        assert {k.split("/")[1] for k in episode if k.startswith("stats/")} == set(
            info["features"])
    stats = json.loads((root / "meta/stats.json").read_text())
    assert set(stats) == set(info["features"])
    assert all(set(s) == STATS for s in stats.values())
    assert np.shape(stats[IMAGE_KEY]["mean"]) == (3, 1, 1)
    assert np.allclose(stats["action"]["mean"], original.labels.reshape(len(original), -1).mean(0))
    has = {lerobot_features.DEPTH_KEY, lerobot_features.STATE_KEY} <= set(info["features"])
    assert has == (original.depths_m is not None)
    if has:  # depth's stats over its finite pixels: JSON holds no inf
        assert np.isclose(stats[lerobot_features.DEPTH_KEY]["max"][0],
                          original.depths_m[np.isfinite(original.depths_m)].max())
        assert info["features"][lerobot_features.STATE_KEY]["names"] == ["j1", "j2", "gripper"]


def test_one_episode_per_demonstration_holds_its_pick_stages(tmp_path):
    original = make(keys=(4, 4, 4, 7, 7, 7))
    root = export_lerobot(original, tmp_path / "out").folder
    data = pq.read_table(root / "data/chunk-000/file-000.parquet")
    assert data.column("episode_index").to_pylist() == [0, 0, 0, 1, 1, 1]
    assert data.column("timestamp").to_pylist() == [0.0, 1.0, 2.0] * 2
    present = np.array(data.column("action.target_present").to_pylist())
    assert present.tolist() == original.target_present().astype(float).tolist()
    assert present[:3].tolist() == [[1, 1, 1], [0, 1, 1], [0, 0, 1]]


def test_episodes_spread_over_several_data_files_when_large(tmp_path, monkeypatch):
    monkeypatch.setattr(lerobot_format, "DATA_FILES_SIZE_IN_MB", 0)  # every episode its own file
    original = make(keys=(0, 0, 1, 2, 2, 2))
    root = export_lerobot(original, tmp_path / "out").folder
    assert len(list(root.glob("data/chunk-000/*.parquet"))) == 3
    assert import_lerobot(root) == original


def test_an_existing_folder_with_files_is_refused(tmp_path):
    (tmp_path / "out").mkdir()
    export_lerobot(make(), tmp_path / "out")  # an empty folder is fine
    with pytest.raises(InvalidInputError, match=r"out_dir = .* a folder that does not exist or"):
        export_lerobot(make(), tmp_path / "out")
    assert [p.name for p in tmp_path.iterdir()] == ["out"]  # no half-written folder left


def test_a_changed_value_is_caught_by_the_checksum(tmp_path):
    root = export_lerobot(make(), tmp_path / "out").folder
    path = root / "data/chunk-000/file-000.parquet"
    table = pq.read_table(path)
    action = np.array(table.column("action").to_pylist(), dtype=np.float32)
    action[0, 0] += 1e-3
    column = pa.FixedSizeListArray.from_arrays(pa.array(action.reshape(-1)), action.shape[1])
    pq.write_table(table.set_column(table.column_names.index("action"), "action", column), path)
    with pytest.raises(LeRobotFolderError, match=re.escape(
            "data/chunk-000/file-000.parquet changed after export")):
        import_lerobot(root)
    gva = json.loads((root / "meta/gva.json").read_text())  # a folder exported before the list:
    del gva["files_sha256"]  # its contents checksum still catches the change
    (root / "meta/gva.json").write_text(json.dumps(gva))
    with pytest.raises(LeRobotFolderError, match="do not match the checksum"):
        import_lerobot(root)


def _edit_json(root, name, change):
    path = root / name
    path.write_text(json.dumps(change(json.loads(path.read_text()))))


def _edit_parquet(root, name, column, values):
    table = pq.read_table(root / name)
    pq.write_table(table.set_column(table.column_names.index(column), column,
                                    pa.array(values, table.schema.field(column).type)),
                   root / name)


@pytest.mark.parametrize(("name", "change", "message"), [
    ("meta/info.json", lambda r: _edit_json(r, "meta/info.json", lambda d: d | {
        "total_episodes": d["total_episodes"] + 1}), "meta/info.json changed after export"),
    ("meta/info.json", lambda r: _edit_json(r, "meta/info.json", lambda d: d | {"fps": -5}),
     "meta/info.json changed after export"),
    ("meta/stats.json", lambda r: _edit_json(r, "meta/stats.json", lambda d: d | {"x": 1}),
     "meta/stats.json changed after export"),
    ("meta/tasks.parquet", lambda r: _edit_parquet(r, "meta/tasks.parquet", "task",
                                                   ["pick", "place"]),
     "meta/tasks.parquet changed after export"),
    ("meta/episodes", lambda r: _edit_parquet(
        r, "meta/episodes/chunk-000/file-000.parquet", "episode_index", [5, 6]),
     "meta/episodes/chunk-000/file-000.parquet changed after export"),
    ("episode_index", lambda r: _edit_parquet(
        r, "data/chunk-000/file-000.parquet", "episode_index", [1, 1, 1, 0, 0, 0]),
     "data/chunk-000/file-000.parquet changed after export"),
    ("deleted", lambda r: (r / "meta/stats.json").unlink(), "lacks meta/stats.json, which the "
     "export wrote"),
    ("added", lambda r: (r / "meta/notes.txt").write_text("mine"), "holds meta/notes.txt, which "
     "the export did not write"),
])
def test_a_folder_changed_anywhere_after_export_is_refused_naming_the_file(tmp_path, name, change,
                                                                          message):
    root = export_lerobot(make(), tmp_path / "out").folder
    import_lerobot(root)  # as exported: accepted
    change(root)
    with pytest.raises(LeRobotFolderError, match=re.escape(message)):
        import_lerobot(root)


def test_folders_gva_did_not_write_are_refused(tmp_path):
    root = export_lerobot(make(), tmp_path / "out").folder
    info = json.loads((root / "meta/info.json").read_text())
    (root / "meta/info.json").write_text(json.dumps(info | {"codebase_version": "v2.1"}))
    with pytest.raises(LeRobotFolderError,
                       match=re.escape("codebase_version is 'v2.1'; gva reads 'v3.0'")):
        import_lerobot(root)
    (root / "meta/info.json").write_text(json.dumps(info))
    (root / "meta/gva.json").unlink()
    with pytest.raises(LeRobotFolderError, match=re.escape("has no meta/gva.json; gva imports")):
        import_lerobot(root)
