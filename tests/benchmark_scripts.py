"""Loads a script of ``benchmarks/`` or ``studies/`` as a module, for the tests that run it.

Benchmarks and studies are scripts, not packages: the script's folder goes on the path (a script
may import a sibling) and the module into ``sys.modules`` (its dataclasses look their module up).
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

ROOT = Path(__file__).resolve().parents[1]
BENCHMARKS = ROOT / "benchmarks"
STUDIES = ROOT / "studies"


def _load_script(folder: Path, name: str) -> ModuleType:
    """``folder/<name>.py`` as the module ``name``."""
    if str(folder) not in sys.path:
        sys.path.insert(0, str(folder))
    spec = importlib.util.spec_from_file_location(name, folder / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def load_benchmark(name: str) -> ModuleType:
    """``benchmarks/<name>.py`` as the module ``name``."""
    return _load_script(BENCHMARKS, name)


def load_study(name: str) -> ModuleType:
    """``studies/<name>.py`` as the module ``name``."""
    return _load_script(STUDIES, name)
