"""The layers of docs/design.md hold: imports point downward only, and no module import cycle.

Inside ``sim``, ``perception`` and ``harness`` the same holds for their rooms (:data:`ROOMS`): a
module imports its own room and the ones before it, and every module is in a room.

Every ``import`` statement counts, wherever it stands: at the top of a module, inside a function,
under ``if TYPE_CHECKING:`` or another condition. Files are found by walking the package folders,
so a new module or sub-package is checked the day it appears.
"""

from __future__ import annotations

import ast
import tomllib
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent

PYBULLET = frozenset({"pybullet", "pybullet_data", "pybullet_utils"})

# Which project packages each package may import (itself included): docs/design.md's
# `experiments -> harness -> sim -> {control, perception}`, with `robots` (URDF data and its
# generator) below them all. A package missing here (a new one) may import nothing of the project.
EVERYTHING = frozenset({"experiments", "harness", "sim", "control", "perception", "robots"})
ALLOWED: Mapping[str, frozenset[str]] = {
    "robots": frozenset({"robots"}),
    "control": frozenset({"control", "robots"}),
    "perception": frozenset({"perception", "robots"}),
    "sim": frozenset({"sim", "control", "perception", "robots"}),
    "harness": frozenset({"harness", "sim", "control", "perception", "robots"}),
    "experiments": EVERYTHING,
    # Importers only: an example runs as it stands; nothing imports a benchmark.
    "examples": EVERYTHING,
    "benchmarks": EVERYTHING,
}

# Outside libraries a package may not import. docs/design.md: control is pure math, "no simulator,
# no torch"; perception is pure learning, "no simulator, no Pinocchio".
BANNED: Mapping[str, frozenset[str]] = {
    "control": frozenset({"torch"}) | PYBULLET,
    "perception": frozenset({"pinocchio", "coal"}) | PYBULLET,
}

# Top-level names of this repository: importing one is a project arrow, checked against ALLOWED.
PROJECT_NAMES = frozenset(ALLOWED) | {"tests"}


@dataclass(frozen=True)
class Import:
    """One imported name: who imports it, where, and the module it lands on in the project."""

    importer: str  # dotted module name, e.g. "perception.models.kqv"
    path: Path  # relative to the repository root
    line: int
    target: str  # the absolute dotted name imported, e.g. "sim.world" or "torch"
    module: str | None  # the project module that import runs, None outside the project

    def where(self) -> str:
        return f"{self.path.as_posix()}:{self.line}"


def discover(root: Path, packages: Iterable[str]) -> dict[str, tuple[Path, bool]]:
    """Every ``.py`` file under ``root/<package>``: dotted name -> (path from root, package?)."""
    modules = {}
    for package in packages:
        for path in sorted((root / package).rglob("*.py")):
            path = path.relative_to(root)
            parts = path.with_suffix("").parts
            if any(part.startswith(".") for part in parts):
                continue
            is_package = parts[-1] == "__init__"
            name = ".".join(parts[:-1] if is_package else parts)
            modules[name] = (path, is_package)
    return modules


def _resolve_relative(importer: str, is_package: bool, level: int, module: str | None) -> str:
    """The absolute name of ``from <level dots><module> import ...`` written in ``importer``."""
    parts = importer.split(".") if is_package else importer.split(".")[:-1]
    if level - 1 >= len(parts):
        raise ValueError(f"{importer}: a relative import of level {level} leaves the package")
    base = parts[: len(parts) - (level - 1)]
    return ".".join([*base, module] if module else base)


def _landing(name: str, modules: Mapping[str, object]) -> str | None:
    """The project module that importing ``name`` runs: the longest prefix that is a module."""
    while name and name not in modules:
        name = name.rpartition(".")[0]
    return name or None


def imports(root: Path, packages: Iterable[str]) -> list[Import]:
    """Every import in the files of ``packages``, relative ones made absolute."""
    modules = discover(root, packages)
    found = []
    for importer, (path, is_package) in modules.items():
        for node in ast.walk(ast.parse((root / path).read_text(encoding="utf-8"), str(path))):
            if isinstance(node, ast.Import):
                targets = [alias.name for alias in node.names]
                found += [Import(importer, path, node.lineno, t, _landing(t, modules))
                          for t in targets]
            elif isinstance(node, ast.ImportFrom):
                source = (node.module or "") if node.level == 0 else _resolve_relative(
                    importer, is_package, node.level, node.module)
                for alias in node.names:
                    # `from pkg import sub` runs pkg.sub when sub is a module; otherwise pkg
                    submodule = f"{source}.{alias.name}"
                    target = submodule if submodule in modules else source
                    found.append(Import(importer, path, node.lineno, target,
                                        _landing(target, modules)))
    return found


def forbidden(found: Iterable[Import]) -> list[str]:
    """One message per import that breaks ALLOWED or BANNED."""
    messages = []
    for imp in found:
        layer, top = imp.importer.split(".")[0], imp.target.split(".")[0]
        if top in PROJECT_NAMES and top not in ALLOWED.get(layer, frozenset()):
            allowed = ", ".join(sorted(ALLOWED.get(layer, ()))) or "nothing of the project"
            messages.append(f"{imp.where()}: {imp.importer} imports {imp.target}; "
                            f"{layer} may import {allowed}")
        elif top in BANNED.get(layer, frozenset()):
            messages.append(f"{imp.where()}: {imp.importer} imports {imp.target}; "
                            f"{layer} never imports {', '.join(sorted(BANNED[layer]))}")
    return messages


def graph(found: Iterable[Import]) -> dict[str, dict[str, Import]]:
    """Module -> {module it imports -> the first import that makes the arrow}."""
    edges: dict[str, dict[str, Import]] = {}
    for imp in found:
        edges.setdefault(imp.importer, {})
        if imp.module is not None and imp.module != imp.importer:
            edges[imp.importer].setdefault(imp.module, imp)
    return edges


def strongly_connected(edges: Mapping[str, Iterable[str]]) -> list[list[str]]:
    """Tarjan's strongly connected components with more than one module, iteratively."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    components = []
    for start in sorted(edges):
        if start in index:
            continue
        work = [(start, iter(sorted(edges.get(start, ()))))]
        index[start] = low[start] = len(index)
        stack.append(start)
        on_stack.add(start)
        while work:
            node, successors = work[-1]
            for succ in successors:
                if succ not in index:
                    index[succ] = low[succ] = len(index)
                    stack.append(succ)
                    on_stack.add(succ)
                    work.append((succ, iter(sorted(edges.get(succ, ())))))
                    break
                if succ in on_stack:
                    low[node] = min(low[node], index[succ])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[node])
                if low[node] == index[node]:
                    component = []
                    while True:
                        member = stack.pop()
                        on_stack.discard(member)
                        component.append(member)
                        if member == node:
                            break
                    if len(component) > 1:
                        components.append(sorted(component))
    return components


def a_cycle(component: list[str], edges: Mapping[str, Mapping[str, Import]]) -> list[Import]:
    """One closed path of imports through a strongly connected component (breadth first)."""
    members, start = set(component), component[0]
    came_from: dict[str, Import] = {}
    frontier = [start]
    while frontier:
        following = []
        for node in frontier:
            for succ, imp in sorted(edges[node].items()):
                if succ not in members or succ in came_from:
                    continue
                came_from[succ] = imp
                following.append(succ)
        if start in came_from:
            break
        frontier = following
    path, node = [], start
    while True:
        path.append(came_from[node])
        node = came_from[node].importer
        if node == start:
            return path[::-1]


def cycles(found: Iterable[Import]) -> list[str]:
    """One message per import cycle: its modules, and the import lines that close it."""
    edges = graph(found)
    messages = []
    for component in strongly_connected({m: list(t) for m, t in edges.items()}):
        steps = "\n".join(f"  {imp.where()}: {imp.importer} imports {imp.target}"
                          for imp in a_cycle(component, edges))
        messages.append(f"import cycle among {', '.join(component)}:\n{steps}")
    return messages


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


# The rooms inside a package (docs/design.md), in order: a module may import its own room and the
# rooms before it, never one after it. A room is a tuple of module names, each standing for the
# module and everything under it. Every module of these packages (but the package's own
# __init__) must be in a room, so a new module is placed the day it appears.
ROOMS: Mapping[str, tuple[tuple[str, ...], ...]] = {
    "sim": (
        ("sim.errors",),
        ("sim.world",),  # the PyBullet world, robot, head camera, looks
        ("sim.tasks",),  # task files, variants, scene sampling, appearance
        ("sim.trials",),  # one pick: runner, execution, records, collector, GIFs
        ("sim.envs",),  # the Gymnasium environment
    ),
    "perception": (
        # base: the interface, the data a model reads and returns, and checks of it
        ("perception.errors", "perception.files", "perception.camera", "perception.poses",
         "perception.sentences", "perception.sentence_reading", "perception.object_spec",
         "perception.catalog", "perception.grasp_tolerance", "perception.grasp_judge",
         "perception.grasps", "perception.interface", "perception.labels", "perception.checks",
         "perception.drawing", "perception.plugins"),
        ("perception.learning",),  # datasets, training, torch pieces, evaluation, checkpoints
        ("perception.models",),  # KQV and the baselines
        ("perception.registry", "perception.model_config_file"),  # models by name
    ),
    "harness": (
        # a run's files: its folder, provenance, records' summary, trial log, job files
        ("harness.run_folder", "harness.provenance", "harness.trial_summary", "harness.trial_log",
         "harness.run_files"),
        # statistics over runs: paired comparisons, the grasp judge over a run's records
        ("harness.paired_statistics", "harness.compare", "harness.calibration",
         "harness.judging"),
        ("harness.jobs",),  # the local pool, and what every pool offers
        ("harness.ray_jobs",),  # the Ray pool
        ("harness.executors",),  # opens the pool a run asked for
        ("harness.run_loop", "harness.run_report"),  # runs of trials, what a run did
    ),
}


def room(module: str, rooms: Mapping[str, tuple[tuple[str, ...], ...]] = ROOMS) -> int | None:
    """The number of ``module``'s room in its package; None outside every room."""
    for number, members in enumerate(rooms.get(module.split(".")[0], ())):
        if any(module == member or module.startswith(member + ".") for member in members):
            return number
    return None


def upward(found: Iterable[Import],
           rooms: Mapping[str, tuple[tuple[str, ...], ...]] = ROOMS) -> list[str]:
    """One message per import from a room of a package to a room after it."""
    messages = []
    for imp in found:
        if imp.module is None or imp.module.split(".")[0] != imp.importer.split(".")[0]:
            continue
        here, there = room(imp.importer, rooms), room(imp.module, rooms)
        if here is not None and there is not None and there > here:
            messages.append(f"{imp.where()}: {imp.importer} imports {imp.target}, "
                            f"room {there} of {imp.importer.split('.')[0]} from room {here}")
    return messages


def roomless(modules: Iterable[str],
             rooms: Mapping[str, tuple[tuple[str, ...], ...]] = ROOMS) -> list[str]:
    """The modules of a package with rooms that are in none (the package's __init__ aside)."""
    return sorted(module for module in modules if module.split(".")[0] in rooms
                  and "." in module and room(module, rooms) is None)


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
                             "room 5 of harness from room 3"]
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
