"""``gva show scene``: the picture is the first image the same scene's demonstration records."""

from __future__ import annotations

import numpy as np
import pytest
from gva_cli import gva
from PIL import Image

from perception.learning.dataset_file import load_dataset


def _shown_and_demonstrated(tmp_path, *options: str) -> tuple[np.ndarray, np.ndarray]:
    """(``gva show scene``'s PNG, ``gva collect``'s first image) of test scene 0, seed 3."""
    scene = ("--scene", "yumi", "--task", "single", "--seed", "3", "--stream", "test", *options)
    status, stdout, stderr = gva("show", "scene", *scene, "--index", "0",
                                 "--out", tmp_path / "scene.png")
    assert status == 0, stderr
    assert "seen through the d435 sensor" in stdout
    status, _, stderr = gva("collect", *scene, "--size", "1", "--out", tmp_path / "demo.gva",
                            "--no-progress")
    assert status == 0, stderr
    shown = np.asarray(Image.open(tmp_path / "scene.png").convert("RGB"))
    return shown, load_dataset(tmp_path / "demo.gva").images[0]


@pytest.mark.slow
def test_the_picture_is_the_demonstrations_first_image_through_each_robots_camera(tmp_path):
    yumi, demonstrated = _shown_and_demonstrated(tmp_path / "yumi")
    np.testing.assert_array_equal(yumi, demonstrated)
    panda, demonstrated = _shown_and_demonstrated(tmp_path / "panda", "--robot", "panda")
    np.testing.assert_array_equal(panda, demonstrated)  # the Panda's workcell and camera
    assert np.abs(panda.astype(int) - yumi.astype(int)).mean() > 5.0  # not the YuMi's


def test_an_unknown_robot_is_refused_naming_those_allowed(tmp_path):
    status, _, stderr = gva("show", "scene", "--scene", "yumi", "--robot", "ur5",
                            "--out", tmp_path / "x.png")
    assert status == 2 and "invalid choice: 'ur5'" in stderr and "panda" in stderr
    assert not (tmp_path / "x.png").exists()
