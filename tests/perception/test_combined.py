"""Several datasets joined for one training (issue 74): every sample kept, each file's scenes
apart, files that disagree refused by field, and the held-out check on demonstrations only."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from user_models import CAMERA, synthetic_dataset

from perception.interface import InvalidInputError, LabelKind
from perception.learning.combined import (
    PART_KEY,
    PARTS_KEY,
    concatenate,
    is_demonstration,
    task_family,
)
from perception.learning.data import Dataset
from perception.learning.validation import split_scenes

LOOKS = {"kind": "randomised", "look_stream": 4, "draw": {}}


def catalog_set(size: int = 12, **kwargs) -> Dataset:
    """Synthetic scenes recorded as ``gva collect --labels catalog --looks randomised`` records
    them: another seed, the task named ``<task>+randomised``, ``labels`` and ``looks`` in extra."""
    data = synthetic_dataset(size=size, seed=7, **kwargs)
    meta = data.metadata
    return replace(data, metadata=replace(meta, task=f"{meta.task}+randomised", extra=meta.extra
                                          | {"labels": "catalog", "looks": LOOKS}))


def test_every_sample_and_label_is_kept_in_order_and_each_files_scenes_apart():
    demos = synthetic_dataset(size=5, kind=LabelKind.GRASP_POSE)
    demos = replace(demos, metadata=replace(demos.metadata, extra={"mirror_symmetric": True,
                                                                   "demonstrations_redrawn": 0}))
    shapes = catalog_set(7, kind=LabelKind.GRASP_POSE)
    joined = concatenate([demos, shapes], ["demo.gva", "shape.gva"])
    assert len(joined) == 12
    for name in ("images", "conditions", "labels"):
        np.testing.assert_array_equal(getattr(joined, name), np.concatenate(
            [getattr(demos, name), getattr(shapes, name)]))
    # each record is its file's, its scene index moved past the first file's and kept
    for record, (k, own) in zip(joined.scenes, [(0, r) for r in demos.scenes] +
                                [(1, r) for r in shapes.scenes], strict=True):
        part = record[PART_KEY]
        assert {key: v for key, v in record.items() if key not in ("index", PART_KEY)} == \
            {key: v for key, v in own.items() if key != "index"}
        assert part["file"] == k and part["index"] == own["index"]
        assert record["index"] == own["index"] + 5 * k
    keys = joined.scene_keys()
    assert set(keys[:5]).isdisjoint(keys[5:]) and len(set(keys)) == 12
    assert keys[:5] == demos.scene_keys()  # the first file's scenes keep their indices
    meta = joined.metadata
    assert (meta.task, meta.size, meta.seed, meta.extra["scenes"]) == ("multiple", 12, 0, 12)
    assert "labels" not in meta.extra and "mirror_symmetric" not in meta.extra  # not shared
    assert [(p["name"], p["task"], p["samples"], p["labels"], p["looks"])
            for p in meta.extra[PARTS_KEY]] == [
        ("demo.gva", "multiple", 5, "picked", "task"),
        ("shape.gva", "multiple+randomised", 7, "catalog", "randomised")]
    assert [is_demonstration(r) for r in joined.scenes] == [True] * 5 + [False] * 7
    assert concatenate([demos]) is demos  # one file: the dataset as it is


def test_files_of_one_task_keep_its_name_and_a_repeated_scene_index_stays_two_scenes():
    a, b = synthetic_dataset(size=3), synthetic_dataset(size=4, seed=1)
    joined = concatenate([a, b])
    assert joined.metadata.task == "multiple" and joined.metadata.extra["scenes"] == 7
    assert joined.scene_keys() == [0, 1, 2, 3, 4, 5, 6]
    assert task_family("selected-type+varied") == "selected-type"


@pytest.mark.parametrize(("other", "message"), [
    (lambda: synthetic_dataset(size=3, image_px=32),
     r"image_height_px of b.gva = 32 is not allowed: a.gva's 64 \(datasets trained on together "
     r"agree on what a model reads and predicts\)"),
    (lambda: synthetic_dataset(size=3, kind=LabelKind.GRASP_POSE),
     r"label_kind of b.gva = 'grasp_pose' is not allowed: a.gva's 'position'"),
    (lambda: synthetic_dataset(size=3, targets=2),
     r"targets of b.gva = 2 is not allowed: a.gva's 1"),
    (lambda: synthetic_dataset(size=3, conditioned=True),
     r"task family of b.gva = 'selected-type' is not allowed: a.gva's 'multiple'"),
    (lambda: synthetic_dataset(size=3, camera=replace(CAMERA, position_m=(0.0, 0.0, 0.7))),
     r"camera of b.gva = \{'position_m': \[0.0, 0.0, 0.7\]\} is not allowed: a.gva's "
     r"\{'position_m': \[0.0, 0.0, 0.6\]\}"),  # the entries that differ only
    (lambda: synthetic_dataset(size=3),
     r"camera of b.gva = None is not allowed: a.gva's \{'position_m'"),
])
def test_datasets_that_disagree_are_refused_naming_the_field_both_values_and_files(
        other, message):
    with pytest.raises(InvalidInputError, match=message):
        concatenate([synthetic_dataset(size=3, camera=CAMERA), other()], ["a.gva", "b.gva"])


def test_arrays_beside_the_images_must_be_in_every_file():
    a = synthetic_dataset(size=3)
    deep = replace(a, depths_m=np.ones((3, 64, 64), np.float32))
    with pytest.raises(InvalidInputError, match=r"arrays of b.gva = \('depths_m',\) is not "
                                                r"allowed: a.gva's \(\)"):
        concatenate([a, deep], ["a.gva", "b.gva"])
    joined = concatenate([deep, deep])
    assert joined.depths_m is not None and joined.depths_m.shape == (6, 64, 64)


@pytest.mark.parametrize("demonstrations_first", [True, False])
def test_the_held_out_scenes_come_only_from_demonstrations(demonstrations_first):
    """And they are the scenes the demonstrations' own split holds out, so the check reads the
    same with and without the extra scenes."""
    demos, shapes = synthetic_dataset(size=10), catalog_set(30)
    parts = [demos, shapes] if demonstrations_first else [shapes, demos]
    joined = concatenate(parts)
    demo_keys = {k for k, r in zip(joined.scene_keys(), joined.scenes, strict=True)
                 if is_demonstration(r)}
    for seed in range(12):
        kept, held = split_scenes(joined, 0.2, seed)
        assert held is not None and len(held) == 2
        assert set(held.scene_keys()) <= demo_keys
        alone = split_scenes(demos, 0.2, seed)[1]
        assert alone is not None
        assert sorted(r[PART_KEY]["index"] for r in held.scenes) == sorted(alone.scene_keys())
        assert len(kept) == 38 and set(kept.scene_keys()).isdisjoint(held.scene_keys())
    # no demonstrations: the split is the one a catalog set alone gets
    only = concatenate([shapes, catalog_set(5)])
    assert split_scenes(only, 0.2, 0)[1] is not None
    # too few demonstrations to hold any out: nothing is, not a catalog scene instead
    few = concatenate([synthetic_dataset(size=2), shapes])
    kept, held = split_scenes(few, 0.2, 0)
    assert held is None and kept is few
