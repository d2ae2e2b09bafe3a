"""A run folder's datasets are what the run asks for: one made otherwise is refused by name."""

from __future__ import annotations

from dataclasses import replace

import pytest

from harness.inputs.collector import (
    APPROACH_HIDDEN_SHARE_MAX,
    APPROACH_MASKED_KEY,
    HIDDEN_SHARE_KEY,
    CollectSettings,
    collect,
)
from harness.run_files import dataset_path, dataset_present
from perception.learning.dataset_file import save_dataset
from robots.yumi import YUMI
from sim.errors import RunFolderError
from sim.tasks.scene_sampling import SeedStream


def test_approach_images_from_before_the_arm_mask_are_another_dataset(tmp_path):
    """A run needs approach images with the arm masked out; a file from before the mask (its
    arm in view, as the first closed-loop runs had it) is refused, naming what differs."""
    path = dataset_path(tmp_path, "single", SeedStream.TRAIN, 1, 0)
    dataset = collect(CollectSettings("yumi", "single", 1, approach_hz=5.0), path, progress=False)
    assert dataset_present(path, "yumi", "single", 1, 0, SeedStream.TRAIN, approach_hz=5.0,
                           robot=YUMI)
    extra = {k: v for k, v in dataset.metadata.extra.items() if k != APPROACH_MASKED_KEY}
    save_dataset(replace(dataset, metadata=replace(dataset.metadata, extra=extra)), path)
    with pytest.raises(RunFolderError, match=r"not the dataset this run needs \(\{'"
                                             r"approach_robot_masked': \(False, True\)\}"):
        dataset_present(path, "yumi", "single", 1, 0, SeedStream.TRAIN, approach_hz=5.0, robot=YUMI)


def test_approach_images_kept_by_another_hidden_share_are_another_dataset(tmp_path):
    """A dataset whose approach images were kept under issue 36's rule (none of a target's
    footprint hidden; it records no share) is not the one a run asks for today, whose images
    may show a target half hidden by the arm (issue 66)."""
    path = dataset_path(tmp_path, "single", SeedStream.TRAIN, 1, 0)
    dataset = collect(CollectSettings("yumi", "single", 1, approach_hz=5.0), path, progress=False)
    assert dataset.metadata.extra[HIDDEN_SHARE_KEY] == APPROACH_HIDDEN_SHARE_MAX
    extra = {k: v for k, v in dataset.metadata.extra.items() if k != HIDDEN_SHARE_KEY}
    save_dataset(replace(dataset, metadata=replace(dataset.metadata, extra=extra)), path)
    with pytest.raises(RunFolderError, match=r"'approach_hidden_share_max': \(0\.0, 0\.5\)"):
        dataset_present(path, "yumi", "single", 1, 0, SeedStream.TRAIN, approach_hz=5.0, robot=YUMI)
