"""The rules of docs/design.md's layers and rooms, and the checker that holds imports to them.

Every ``import`` statement counts, wherever it stands: at the top of a module, inside a function,
under ``if TYPE_CHECKING:`` or another condition. Files are found by walking the package folders,
so a new module or sub-package is checked the day it appears. ``tests/test_layers.py`` runs the
checker on the project and on small packages.
"""

from __future__ import annotations

import ast
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path

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
    # Importers only: an example runs as it stands; nothing imports a benchmark or a study.
    "examples": EVERYTHING,
    "benchmarks": EVERYTHING,
    "studies": EVERYTHING,
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


# The rooms inside a package (docs/design.md), in order: a module may import its own room and the
# rooms before it, never one after it. A room is a tuple of module names, each standing for the
# module and everything under it. Every module of these packages (but the package's own
# __init__) must be in a room, so a new module is placed the day it appears.
ROOMS: Mapping[str, tuple[tuple[str, ...], ...]] = {
    "sim": (
        ("sim.errors",),
        ("sim.world",),  # the PyBullet world, robot, head camera, looks
        ("sim.tasks",),  # task files, variants, scene sampling, appearance
        # one pick: runner, execution, records, the model by name, GIFs; with sub-packages:
        # sim.trials.closed_loop, the closed loop's picks, its settings and what a frame shows
        # of a target while the arm is in view
        ("sim.trials",),
        ("sim.envs",),  # the Gymnasium environment
    ),
    "perception": (
        # base: the interface, the data a model reads and returns, and checks of it
        # (with three sub-packages: perception.language, sentence embeddings and which target a
        # sentence names; perception.objects, the object types, what they are made of and their
        # grasps; perception.judge, the grasp judge and its tolerance map)
        ("perception.errors", "perception.files", "perception.camera", "perception.poses",
         "perception.language", "perception.objects", "perception.judge", "perception.interface",
         "perception.labels", "perception.checks", "perception.drawing", "perception.plugins"),
        ("perception.learning",),  # datasets, training, torch pieces, evaluation, checkpoints
        ("perception.models",),  # KQV and the baselines
        ("perception.registry", "perception.model_config_file"),  # models by name
        ("perception.remote",),  # models served over a websocket, and their clients
    ),
    "harness": (
        # what a run is made of: its trial settings (identity, inputs, held-out check) and the
        # datasets it trains on (collect)
        ("harness.inputs",),
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
    "experiments": (
        ("experiments.tables",),  # what both tables share
        # what every command's options are made of: options declared once, argparse types,
        # the options of the commands that pick
        ("experiments.commands.options", "experiments.commands.arguments",
         "experiments.commands.pick_options"),
        ("experiments.table2", "experiments.table3"),  # one folder per table
        ("experiments.commands",),  # one module per gva command or family
        ("experiments.cli",),  # the gva entry point
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


# The house rule of issue 78: a package folder holds at most this many flat modules (``.py``
# files beside its __init__, the __init__ not counted); past it, a part of it gets a room of its
# own, a sub-package.
MAX_FLAT_MODULES = 15


def crowded(root: Path, packages: Iterable[str], limit: int = MAX_FLAT_MODULES) -> list[str]:
    """One message per package folder under ``root/<package>`` with more than ``limit`` flat
    modules: every folder with an ``__init__.py`` (the package's own included)."""
    messages = []
    for package in packages:
        for init in sorted((root / package).rglob("__init__.py")):
            folder = init.parent.relative_to(root)
            if any(part.startswith(".") for part in folder.parts):
                continue
            count = sum(1 for path in init.parent.glob("*.py") if path.name != "__init__.py")
            if count > limit:
                messages.append(f"{folder.as_posix()}/ holds {count} flat modules, "
                                f"more than {limit}")
    return messages
