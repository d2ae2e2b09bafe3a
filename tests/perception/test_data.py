import dataclasses
import json
import re
from dataclasses import replace

import numpy as np
import pytest
from safetensors import safe_open
from safetensors.numpy import save_file

import perception.learning.dataset_file as dataset_file
from perception.interface import ConditionKind, InvalidInputError, LabelKind
from perception.labels import label_vector, split_label
from perception.learning.data import FORMAT_VERSION, Dataset, DatasetMetadata
from perception.learning.dataset_file import (
    HEADER_KEY,
    DatasetError,
    load_dataset,
    read_metadata,
    save_dataset,
)


def rotations(rng: np.random.Generator, n: int) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(n, 3, 3)))
    q = q * np.sign(np.diagonal(r, axis1=1, axis2=2))[:, None, :]
    return q * np.linalg.det(q)[:, None, None]  # (n, 3, 3), det +1


def make(kind=LabelKind.POSITION, choices=("mug", "box"), size=5, seed=0, h=8, w=6, q=2):
    rng = np.random.default_rng(seed)
    metadata = DatasetMetadata(
        scene="paper-sim", task="selected-type", size=size, seed=seed, image_height_px=h,
        image_width_px=w, label_kind=kind, targets=q,
        condition_kind=ConditionKind.OBJECT_TYPE if choices else ConditionKind.NONE,
        condition_choices=choices, camera={"position_m": (0.0, 0.1, 1.2), "fov_deg": 58.0},
        extra={"demonstrations_redrawn": 1})
    position = rng.uniform(-0.3, 0.3, (size, q, 3))
    rotation = rotations(rng, size * q).reshape(size, q, 3, 3) if kind is LabelKind.GRASP_POSE \
        else None
    conditions = np.eye(len(choices), dtype=np.float32)[rng.integers(len(choices), size=size)] \
        if choices else np.zeros((size, 0), np.float32)
    scenes = tuple({"index": i, "objects": [{"type": "mug", "position_xy_m": (0.1 * i, 0.0)}]}
                   for i in range(size))
    return Dataset(metadata, rng.integers(0, 256, (size, h, w, 3), dtype=np.uint8), conditions,
                   label_vector(position, rotation), scenes)


def rewrite(path, change=None, tensors=None, drop=()):
    """Rewrites a dataset file with safetensors' own writer, changing its record or tensors."""
    with safe_open(str(path), framework="numpy") as file:
        record = json.loads(file.metadata()[HEADER_KEY])
        arrays = {name: file.get_tensor(name) for name in file.keys()}
    if change:
        change(record)
    arrays.update(tensors or {})
    for name in drop:
        arrays.pop(name)
    save_file(arrays, str(path), metadata={HEADER_KEY: json.dumps(record)})


def fails(path, message, **kwargs):
    with pytest.raises(DatasetError, match=re.escape(message)) as caught:
        load_dataset(path, **kwargs)
    assert str(path) in str(caught.value)


@pytest.mark.parametrize(("kind", "choices", "size"), [
    (LabelKind.POSITION, ("mug", "box"), 5), (LabelKind.GRASP_POSE, ("mug", "box", "can"), 5),
    (LabelKind.POSITION, (), 5), (LabelKind.GRASP_POSE, (), 0)])
def test_round_trip_gives_the_same_dataset(tmp_path, kind, choices, size):
    dataset = make(kind, choices, size)
    path = save_dataset(dataset, tmp_path / "sub" / "train.safetensors")
    loaded = load_dataset(path)
    assert loaded == dataset and len(loaded) == size
    assert loaded.labels.shape == (size, 2, 3 if kind is LabelKind.POSITION else 12)
    assert loaded.conditions.shape == (size, len(choices))
    assert read_metadata(path) == dataset.metadata
    assert loaded.metadata.camera["position_m"] == [0.0, 0.1, 1.2]  # the JSON form, as saved
    assert [p.name for p in path.parent.iterdir()] == ["train.safetensors"]  # no temporary left


def test_depth_and_joints_are_kept_where_given_and_old_files_stay_as_they_were(tmp_path):
    plain = make(kind=LabelKind.GRASP_POSE, size=4)
    save_dataset(plain, tmp_path / "plain.gva")
    before = (tmp_path / "plain.gva").read_bytes()
    rng = np.random.default_rng(1)
    meta = replace(plain.metadata, extra=plain.metadata.extra | {"joint_names": ["a", "b"]})
    rich = replace(plain, metadata=meta, depths_m=rng.uniform(0.3, 1.0, (4, 8, 6)).astype(
        np.float32), joint_positions=rng.normal(size=(4, 2)).astype(np.float32))
    save_dataset(rich, tmp_path / "rich.gva")
    loaded = load_dataset(tmp_path / "rich.gva")
    assert loaded == rich and loaded != replace(rich, depths_m=None)
    assert loaded.subset([2, 0]).joint_positions.tolist() == rich.joint_positions[[2, 0]].tolist()
    save_dataset(load_dataset(tmp_path / "plain.gva"), tmp_path / "plain.gva")
    assert (tmp_path / "plain.gva").read_bytes() == before  # no optional tensor: the same file
    with pytest.raises(InvalidInputError, match=r"joint_positions = 'float32 \(4, 3\)'"):
        replace(rich, joint_positions=np.zeros((4, 3), np.float32))  # 2 names, 3 columns
    with pytest.raises(InvalidInputError, match=r"depths_m = 'float64"):
        replace(rich, depths_m=rich.depths_m.astype(np.float64))
    rewrite(tmp_path / "rich.gva", tensors={"depths_m": np.zeros((4, 8, 6), np.float32)})
    fails(tmp_path / "rich.gva", "contents do not match their checksum")


def test_same_dataset_same_bytes_and_another_seed_other_bytes(tmp_path):
    first = save_dataset(make(), tmp_path / "a.safetensors").read_bytes()
    assert save_dataset(make(), tmp_path / "b.safetensors").read_bytes() == first
    dataset = make()
    other_seed = Dataset(DatasetMetadata(**{**vars(dataset.metadata), "seed": 1}),
                         dataset.images, dataset.conditions, dataset.labels, dataset.scenes)
    assert save_dataset(other_seed, tmp_path / "c.safetensors").read_bytes() != first


def test_crashed_write_leaves_the_old_file_and_no_temporary(tmp_path, monkeypatch):
    path = save_dataset(make(seed=0), tmp_path / "d.safetensors")
    before = path.read_bytes()

    def crash(tensors, filename, metadata):
        open(filename, "wb").write(b"half a dataset")
        raise OSError("disk full")

    monkeypatch.setattr(dataset_file, "save_file", crash)
    with pytest.raises(OSError, match="disk full"):
        save_dataset(make(seed=1), path)
    assert path.read_bytes() == before and len(list(tmp_path.iterdir())) == 1


def test_label_helpers_share_one_layout():
    rng = np.random.default_rng(3)
    position, rotation = rng.normal(size=(4, 2, 3)), rotations(rng, 8).reshape(4, 2, 3, 3)
    vector = label_vector(position, rotation)
    assert vector.shape == (4, 2, 12) and vector.dtype == np.float32
    np.testing.assert_allclose(vector[0, 0, 3:6], rotation[0, 0, 0], atol=1e-6)  # row-major
    parts = split_label(vector)
    np.testing.assert_allclose(parts.position_m, position, atol=1e-6)
    np.testing.assert_allclose(parts.rotation, rotation, atol=1e-6)
    assert split_label(label_vector([0.4, 0.0, 0.1])).rotation is None
    with pytest.raises(InvalidInputError, match=r"rotation = .* is not allowed: rotations"):
        label_vector([0.4, 0.0, 0.1], np.diag([1.0, 1.0, -1.0]))
    with pytest.raises(InvalidInputError, match=re.escape("label = 'shape (4,)'")):
        split_label(np.zeros(4))


def test_metadata_and_dataset_name_the_bad_field():
    good = make().metadata
    with pytest.raises(InvalidInputError, match="size = -1 is not allowed: an integer >= 0"):
        DatasetMetadata(**{**vars(good), "size": -1})
    with pytest.raises(InvalidInputError, match=r"condition_choices = .* exactly when"):
        DatasetMetadata(**{**vars(good), "condition_kind": ConditionKind.NONE})
    with pytest.raises(InvalidInputError, match=r"camera = .* JSON-able"):
        DatasetMetadata(**{**vars(good), "camera": {"fov_deg": float("nan")}})
    dataset = make()
    with pytest.raises(InvalidInputError, match=re.escape(
            "images = 'uint8 (5, 8, 7, 3)' is not allowed: uint8 (N, H, W, 3) = (5, 8, 6, 3)")):
        Dataset(dataset.metadata, np.zeros((5, 8, 7, 3), np.uint8), dataset.conditions,
                dataset.labels, dataset.scenes)
    with pytest.raises(InvalidInputError, match=re.escape("labels = 'float64 (5, 2, 3)'")):
        Dataset(dataset.metadata, dataset.images, dataset.conditions,
                dataset.labels.astype(np.float64), dataset.scenes)
    with pytest.raises(InvalidInputError, match=re.escape("conditions[0] = [1.0, 1.0]")):
        Dataset(dataset.metadata, dataset.images, np.ones((5, 2), np.float32), dataset.labels,
                dataset.scenes)
    with pytest.raises(InvalidInputError, match=r"scenes = '4 records' .* one per sample"):
        Dataset(dataset.metadata, dataset.images, dataset.conditions, dataset.labels,
                dataset.scenes[:4])


def test_subset_keeps_the_chosen_samples_in_order(tmp_path):
    dataset = make(LabelKind.GRASP_POSE, size=6)
    part = dataset.subset([4, 1])
    assert len(part) == 2 and part.metadata.size == 2 and part.metadata.seed == 0
    assert np.array_equal(part.images, dataset.images[[4, 1]])
    assert np.array_equal(part.labels[1], dataset.labels[1])
    assert part.scenes == (dataset.scenes[4], dataset.scenes[1])
    assert load_dataset(save_dataset(part, tmp_path / "p.safetensors")) == part
    assert len(dataset.subset([])) == 0
    for bad, allowed in (([6], r"\[0, 6\)"), ([1, 1], "distinct"), ([True], "integers")):
        with pytest.raises(InvalidInputError, match=allowed):
            dataset.subset(bad)


def test_target_types_come_from_the_scene_records_and_index_the_vocabulary(tmp_path):
    dataset = make(size=4, q=2)  # its records name objects but no targets
    records = ({"objects": [{"type": "mug"}, {"type": "box"}], "targets": [1, 0]},
               {"objects": [{"type": "can"}, {"type": "mug"}], "targets": [0, 1]},
               {"objects": [{"type": "box"}], "targets": [0]},  # a second target unnamed
               {"index": 3})
    typed = dataclasses.replace(dataset, scenes=records, metadata=dataclasses.replace(
        dataset.metadata, extra={"object_types": ["mug", "box"]}))
    assert typed.target_types() == (("box", "mug"), ("can", "mug"), ("box", None),
                                    (None, None))
    indices = typed.target_type_indices()
    assert indices.dtype == np.int64
    np.testing.assert_array_equal(indices, [[1, 0], [-1, 0], [1, -1], [-1, -1]])  # can: unknown
    loaded = load_dataset(save_dataset(typed, tmp_path / "typed.gva"))
    np.testing.assert_array_equal(loaded.target_type_indices(), indices)
    untyped = dataclasses.replace(typed, metadata=dataset.metadata)  # no vocabulary
    np.testing.assert_array_equal(untyped.target_type_indices(), np.full((4, 2), -1))
    assert typed.subset([]).target_type_indices().shape == (0, 2)


def test_missing_odd_or_foreign_files_are_refused(tmp_path):
    fails(tmp_path / "none.safetensors", "no such file")
    fails(tmp_path, "not a file")
    (tmp_path / "notes.txt").write_text("hello, these are not tensors")
    fails(tmp_path / "notes.txt", "not a safetensors file")
    (tmp_path / "tiny").write_bytes(b"\x01")
    fails(tmp_path / "tiny", "not a safetensors file")
    save_file({"x": np.zeros(3, np.float32)}, str(tmp_path / "plain.safetensors"))
    fails(tmp_path / "plain.safetensors", "not a gva dataset: no 'gva.dataset' entry")


def test_truncated_lengthened_or_damaged_files_are_refused(tmp_path):
    path = save_dataset(make(h=64, w=64), tmp_path / "t.safetensors")
    whole = path.read_bytes()
    path.write_bytes(whole[: len(whole) // 2])
    fails(path, f"truncated: {len(whole) // 2} bytes, the header describes {len(whole)}")
    path.write_bytes(whole[:40])
    fails(path, "truncated: 40 bytes, but the header alone needs")
    path.write_bytes(whole + b"\0")
    fails(path, f"longer than its header says: {len(whole) + 1} bytes")
    path.write_bytes(whole[:9] + b"x" + whole[10:])  # the first key's opening quote
    fails(path, "the header JSON is damaged")
    with pytest.raises(DatasetError, match="the header JSON is damaged"):
        read_metadata(path)


def test_a_changed_byte_is_caught_by_the_checksum(tmp_path):
    path = save_dataset(make(), tmp_path / "c.safetensors")
    whole = bytearray(path.read_bytes())
    length = int.from_bytes(whole[:8], "little")
    start, end = json.loads(whole[8: 8 + length])["images"]["data_offsets"]
    whole[8 + length + (start + end) // 2] ^= 0x01
    path.write_bytes(bytes(whole))
    message = "contents do not match their checksum: the file was changed or damaged after it " \
              "was written"
    fails(path, message)
    save_dataset(make(), path)
    rewrite(path, lambda record: record["metadata"].update(seed=7))  # an edited header
    fails(path, message)


@pytest.mark.parametrize("version", [FORMAT_VERSION + 1, FORMAT_VERSION - 1])
def test_other_format_versions_are_refused(tmp_path, version):
    path = save_dataset(make(), tmp_path / "v.safetensors")
    rewrite(path, lambda record: record["metadata"].update(format_version=version))
    fails(path, f"written by format version {version}; this gva reads version {FORMAT_VERSION}")
    with pytest.raises(DatasetError, match=f"written by format version {version}"):
        read_metadata(path)


def test_missing_or_inconsistent_parts_are_refused(tmp_path):
    path = tmp_path / "m.safetensors"
    dataset = make()
    cases = [
        ({"change": lambda r: r["metadata"].pop("seed")}, "metadata lacks keys seed; version 1"),
        ({"change": lambda r: r["metadata"].update(owner="x")}, "metadata has unknown keys owner"),
        ({"change": lambda r: r.pop("contents_sha256")}, "'gva.dataset' entry lacks contents"),
        ({"change": lambda r: r["metadata"].update(label_kind="pose")},
         "metadata is not valid: label_kind = 'pose' is not allowed: one of position, grasp_pose"),
        ({"drop": ["labels"]}, "lacks tensors labels"),
        ({"tensors": {"images": dataset.images[:, :4]}},
         "tensor images is U8 of shape (5, 4, 6, 3); the metadata says U8 (N, H, W, 3) = "
         "(5, 8, 6, 3)"),
        ({"tensors": {"labels": dataset.labels.astype(np.float64)}},
         "tensor labels is F64 of shape (5, 2, 3); the metadata says F32 (N, q, D) = (5, 2, 3)"),
        ({"tensors": {"extra": np.zeros(1, np.float32)}}, "has unexpected tensors extra"),
    ]
    for change, message in cases:
        save_dataset(dataset, path)
        rewrite(path, **change)
        fails(path, message)


def test_expect_names_the_field_the_file_value_and_the_wanted_value(tmp_path):
    path = save_dataset(make(), tmp_path / "e.safetensors")
    wanted = {"scene": "paper-sim", "label_kind": LabelKind.POSITION,
              "condition_choices": ("mug", "box"), "image_height_px": 8}
    assert len(load_dataset(path, expect=wanted)) == 5
    fails(path, "not the dataset asked for: scene is 'paper-sim' in the file, expected 'yumi'; "
                "task is 'selected-type' in the file, expected 'single'; image_height_px is 8 "
                "in the file, expected 128",
          expect={"scene": "yumi", "task": "single", "image_height_px": 128})
    fails(path, "label_kind is 'position' in the file, expected 'grasp_pose'",
          expect={"label_kind": LabelKind.GRASP_POSE})
    with pytest.raises(InvalidInputError, match=r"expect = \['camera_fov'\] is not allowed"):
        load_dataset(path, expect={"camera_fov": 58.0})
