"""The layers of docs/design.md hold: imports point downward only, and no module import cycle.

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


# sim's rooms (docs/design.md), in order: each may import the rooms before it, never one after it.
SIM_ROOMS = ("sim.world", "sim.tasks", "sim.trials", "sim.envs")


def _room(module: str) -> int | None:
    return next((number for number, room in enumerate(SIM_ROOMS)
                 if module == room or module.startswith(room + ".")), None)


def test_sim_rooms_import_only_the_rooms_before_them(project_imports):
    messages = [f"{imp.where()}: {imp.importer} imports {imp.target}"
                for imp in project_imports
                if imp.module is not None and None not in (_room(imp.importer), _room(imp.module))
                and _room(imp.module) > _room(imp.importer)]
    assert not messages, "imports up sim's rooms (world <- tasks <- trials <- envs):\n" + \
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
