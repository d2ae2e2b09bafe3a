"""The layers of docs/design.md hold: imports point downward only, and no module import cycle.

Inside ``sim``, ``perception``, ``harness`` and ``experiments`` the same holds for their rooms
(``ROOMS``): a module imports its own room and the ones before it, and every module is in a
room. The rules and the checker: ``tests/layer_rules.py``.
"""

from __future__ import annotations

import tomllib
from collections.abc import Mapping
from pathlib import Path

import pytest
from layer_rules import (
    ALLOWED,
    MAX_FLAT_MODULES,
    ROOMS,
    Import,
    crowded,
    cycles,
    discover,
    forbidden,
    imports,
    roomless,
    upward,
)

ROOT = Path(__file__).resolve().parent.parent


# --- the project ---

@pytest.fixture(scope="module")
def project_imports() -> list[Import]:
    return imports(ROOT, ALLOWED)


def test_every_package_has_a_layer():
    find = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"]
    packages = {pattern.rstrip("*") for pattern in find["find"]["include"]}
    assert packages <= set(ALLOWED), f"give {sorted(packages - set(ALLOWED))} a row in ALLOWED"
    mypy = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["mypy"]["packages"])
    assert mypy == packages, "[tool.mypy] packages and the packages setuptools finds differ"


def test_the_walk_finds_every_package(project_imports):
    importers = {imp.importer.split(".")[0] for imp in project_imports}
    assert importers == set(ALLOWED)
    assert any(imp.importer == "perception.models.kqv" for imp in project_imports)


def test_imports_point_down_the_layers(project_imports):
    messages = forbidden(project_imports)
    assert not messages, "imports against docs/design.md's layers:\n" + "\n".join(messages)


def test_no_import_cycle(project_imports):
    messages = cycles(project_imports)
    assert not messages, "\n".join(messages)


def test_every_module_has_a_room():
    missing = roomless(discover(ROOT, ROOMS))
    assert not missing, f"give {missing} a room in ROOMS (and in docs/design.md)"


def test_every_room_holds_a_module():
    modules = discover(ROOT, ROOMS)
    empty = [member for members in (m for rs in ROOMS.values() for m in rs) for member in members
             if not any(name == member or name.startswith(member + ".") for name in modules)]
    assert not empty, f"{empty} name no module: remove them from ROOMS"


def test_rooms_import_only_the_rooms_before_them(project_imports):
    messages = upward(project_imports)
    assert not messages, "imports up a package's rooms (ROOMS, docs/design.md):\n" + \
        "\n".join(messages)


def test_no_package_folder_holds_more_flat_modules_than_the_house_rule():
    messages = crowded(ROOT, ALLOWED)
    assert not messages, (f"package folders past the house rule of {MAX_FLAT_MODULES} flat "
                          "modules (issue 78; give a part of each a sub-package):\n"
                          + "\n".join(messages))


# --- the checker itself, on a tiny package ---

def write(root: Path, files: Mapping[str, str]) -> None:
    for name, text in files.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)


def test_relative_imports_resolve(tmp_path):
    write(tmp_path, {
        "sim/__init__.py": "from . import world\n",
        "sim/world.py": "from .tasks import load\nfrom .rooms import trials\n",
        "sim/tasks.py": "",
        "sim/rooms/__init__.py": "from .. import tasks\nfrom .trials import run\n",
        "sim/rooms/trials.py": "from ..tasks import load\nfrom .. import rooms\n",
    })
    found = {(imp.importer, imp.target, imp.module) for imp in imports(tmp_path, ["sim"])}
    assert found == {
        ("sim", "sim.world", "sim.world"),
        ("sim.world", "sim.tasks", "sim.tasks"),
        ("sim.world", "sim.rooms.trials", "sim.rooms.trials"),
        ("sim.rooms", "sim.tasks", "sim.tasks"),
        ("sim.rooms", "sim.rooms.trials", "sim.rooms.trials"),
        ("sim.rooms.trials", "sim.tasks", "sim.tasks"),
        ("sim.rooms.trials", "sim.rooms", "sim.rooms"),
    }


def test_a_relative_import_above_the_top_package_is_an_error(tmp_path):
    write(tmp_path, {"sim/__init__.py": "", "sim/world.py": "from ..control import ik\n"})
    with pytest.raises(ValueError, match=r"sim\.world: a relative import of level 2 leaves"):
        imports(tmp_path, ["sim"])


def test_a_forbidden_arrow_is_found_where_it_hides(tmp_path):
    write(tmp_path, {
        "control/__init__.py": "",
        "control/ik.py": "def solve():\n    if True:\n        from sim.world import World\n",
        "perception/__init__.py": "",
        "perception/model.py": "import torch\n\n\nclass M:\n    def f(self):\n"
                               "        import pybullet_data\n",
        "sim/__init__.py": "",
        "sim/world.py": "from control import ik\nimport perception.model\n",
    })
    messages = forbidden(imports(tmp_path, ["control", "perception", "sim"]))
    assert messages == [
        "control/ik.py:3: control.ik imports sim.world; control may import control, robots",
        "perception/model.py:6: perception.model imports pybullet_data; perception never "
        "imports coal, pinocchio, pybullet, pybullet_data, pybullet_utils",
    ]


def test_a_cycle_through_a_function_level_import_is_found(tmp_path):
    write(tmp_path, {
        "experiments/__init__.py": "",
        "experiments/table2/__init__.py": "",
        "experiments/table2/run.py": "from experiments.table2 import report\n",
        "experiments/table2/report.py": "from .figures import plot\n",
        "experiments/table2/figures.py": "def plot():\n    from . import run\n",
        "experiments/cli.py": "from experiments.table2 import run\n",
    })
    messages = cycles(imports(tmp_path, ["experiments"]))
    assert messages == [
        "import cycle among experiments.table2.figures, experiments.table2.report, "
        "experiments.table2.run:\n"
        "  experiments/table2/figures.py:2: experiments.table2.figures imports "
        "experiments.table2.run\n"
        "  experiments/table2/run.py:1: experiments.table2.run imports "
        "experiments.table2.report\n"
        "  experiments/table2/report.py:1: experiments.table2.report imports "
        "experiments.table2.figures",
    ]


def test_no_cycle_no_message(tmp_path):
    write(tmp_path, {"sim/__init__.py": "", "sim/a.py": "from sim import b\n", "sim/b.py": ""})
    assert cycles(imports(tmp_path, ["sim"])) == []


def test_an_import_up_the_rooms_is_found_where_it_hides(tmp_path):
    # The loop issue 65 removed, put back in the run layer: the executor opens the Ray pool
    # inside a function, and the Ray pool reaches up to the run loop that opens the executor.
    write(tmp_path, {
        "harness/__init__.py": "",
        "harness/jobs.py": "",
        "harness/executors.py": "from harness.jobs import Pool\n\n\ndef open_pool():\n"
                                "    from harness.ray_jobs import RayPool\n",
        "harness/ray_jobs.py": "from harness.jobs import Job\n\n\ndef _sees():\n"
                               "    from harness.run_loop import git_revision\n",
        "harness/run_loop.py": "from harness.executors import open_pool\n",
    })
    found = imports(tmp_path, ["harness"])
    assert upward(found) == ["harness/ray_jobs.py:5: harness.ray_jobs imports harness.run_loop, "
                             "room 6 of harness from room 4"]
    assert cycles(found) == [
        "import cycle among harness.executors, harness.ray_jobs, harness.run_loop:\n"
        "  harness/executors.py:5: harness.executors imports harness.ray_jobs\n"
        "  harness/ray_jobs.py:5: harness.ray_jobs imports harness.run_loop\n"
        "  harness/run_loop.py:1: harness.run_loop imports harness.executors",
    ]


def test_the_old_loop_through_modules_outside_the_rooms_is_found(tmp_path):
    # Before issue 65: sim.trials.run_loop -> sim.executors -> (in a function) sim.ray_jobs ->
    # sim.trials.provenance. No module cycle, but a room cycle through modules in no room.
    write(tmp_path, {
        "sim/__init__.py": "",
        "sim/trials/__init__.py": "",
        "sim/trials/provenance.py": "",
        "sim/trials/run_loop.py": "from sim.executors import open_pool\n",
        "sim/executors.py": "def open_pool():\n    from sim.ray_jobs import RayPool\n",
        "sim/ray_jobs.py": "from sim.trials.provenance import git_revision\n",
    })
    assert cycles(imports(tmp_path, ["sim"])) == []
    assert roomless(discover(tmp_path, ["sim"])) == ["sim.executors", "sim.ray_jobs"]


def test_only_imports_up_the_rooms_are_reported(tmp_path):
    write(tmp_path, {
        "perception/__init__.py": "",
        "perception/interface.py": "",
        "perception/learning/__init__.py": "from perception import interface\n",
        "perception/models/__init__.py": "",
        "perception/models/kqv.py": "from typing import TYPE_CHECKING\n\nif TYPE_CHECKING:\n"
                                    "    from perception.learning import train\n",
        "perception/learning/train.py": "def f():\n    from perception.models import kqv\n",
    })
    assert upward(imports(tmp_path, ["perception"])) == [
        "perception/learning/train.py:2: perception.learning.train imports "
        "perception.models.kqv, room 2 of perception from room 1"]


def test_a_crowded_package_folder_is_found_with_its_count(tmp_path):
    write(tmp_path, {
        "sim/__init__.py": "",
        **{f"sim/m{i}.py": "" for i in range(3)},
        "sim/trials/__init__.py": "",
        **{f"sim/trials/t{i}.py": "" for i in range(4)},
        "sim/trials/closed_loop/__init__.py": "",
        "sim/trials/closed_loop/loop.py": "",
        **{f"sim/assets/a{i}.py": "" for i in range(5)},  # not a package: no __init__
    })
    assert crowded(tmp_path, ["sim"], limit=3) == ["sim/trials/ holds 4 flat modules, more than 3"]
    assert crowded(tmp_path, ["sim"], limit=4) == []
