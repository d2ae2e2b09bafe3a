"""Plug-ins found by path and by the name an installed package registers (``gva.models``)."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from perception.errors import InvalidInputError
from perception.plugins import ENTRY_POINT_GROUP, build_plugin, installed_models, plugin_class

ROOT = Path(__file__).resolve().parents[2]

PACKAGE_PYPROJECT = f"""
[build-system]
requires = ["setuptools>=77"]
build-backend = "setuptools.build_meta"

[project]
name = "tiny-gva-plugin"
version = "0.1"

[project.entry-points."{ENTRY_POINT_GROUP}"]
tiny-grasp = "tiny_gva_plugin:TinyGrasp"
"""

PACKAGE_MODULE = '''
"""A plug-in package: a grasp straight down at the workspace's centre."""

import numpy as np

from perception.interface import LabelKind, PerceptionModel, Prediction, Target


class TinyGrasp(PerceptionModel):
    name = "tiny-grasp"
    label_kind = LabelKind.GRASP_POSE

    def predict(self, image, condition):
        down = np.diag([1.0, -1.0, -1.0])
        return Prediction((Target(np.array([0.47, 0.0, 0.03]), down),))
'''


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """A tiny package with a ``gva.models`` entry point, ``pip install``-ed into a site folder.

    The folder (``pip install --target``) stands in for the venv's site-packages, so the test
    never changes the venv it runs in; Python finds its entry points as it finds a venv's.
    """
    root = tmp_path_factory.mktemp("plugin")
    package = root / "tiny-gva-plugin"
    package.mkdir()
    (package / "pyproject.toml").write_text(PACKAGE_PYPROJECT)
    (package / "tiny_gva_plugin.py").write_text(textwrap.dedent(PACKAGE_MODULE))
    site = root / "site"
    subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps",
                    "--no-build-isolation", "--no-index", "--target", str(site), str(package)],
                   check=True, capture_output=True, text=True)
    return site


def _python(site: Path, code: str) -> subprocess.CompletedProcess[str]:
    path = os.pathsep.join([str(ROOT), str(site), os.environ.get("PYTHONPATH", "")])
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env=os.environ | {"PYTHONPATH": path}, timeout=300)


def test_an_installed_plugin_is_found_by_its_registered_name(installed):
    result = _python(installed, "from perception.registry import model_class; "
                     "print(model_class('tiny-grasp').__name__)")
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "TinyGrasp"


def test_an_installed_plugin_runs_trials_by_its_name(installed, tmp_path):
    result = _python(installed, "import sys; from experiments.cli import main; sys.exit(main("
                     f"['trials', '--model', 'tiny-grasp', '--n', '1', '--out', '{tmp_path}', "
                     "'--no-progress']))")
    assert result.returncode == 0, result.stderr
    assert '"model": "tiny-grasp"' in (tmp_path / "trials.jsonl").read_text()


def test_a_name_nothing_registers_lists_what_is_installed():
    assert "tiny-grasp" not in installed_models()  # this process never saw the package
    with pytest.raises(InvalidInputError, match=r"model = 'tiny-grasp' is not allowed: a model "
                       r"name an installed package registers in 'gva.models'"):
        plugin_class("tiny-grasp")


def test_a_class_path_builds_with_no_arguments():
    """``build_plugin`` returns a built model, not the class: its name alone would pass both."""
    import numpy as np
    import user_models

    model = build_plugin("user_models:FixedGrasp")
    assert not isinstance(model, type) and type(model) is user_models.FixedGrasp
    assert model.name == "fixed-grasp"
    (target,) = model.predict(np.zeros((64, 64, 3), np.uint8)).targets
    np.testing.assert_array_equal(target.position_m, [0.47, 0.0, 0.03])


def test_a_module_that_raises_on_import_is_one_clear_error(tmp_path, monkeypatch):
    (tmp_path / "broken_plugin.py").write_text("raise RuntimeError('needs a GPU')\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(InvalidInputError, match=r"importing module 'broken_plugin' raised "
                       r"RuntimeError: needs a GPU"):
        plugin_class("broken_plugin:Model")
