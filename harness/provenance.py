"""What made a result: the code, the libraries, the inputs' hashes and the command.

A run folder's ``run.json`` keeps one entry per session that worked on it (a resumed run adds
one), and every summary carries the entry of the session that wrote it, so a number can be
traced to the code revision, the library versions and the exact checkpoint and task file that
produced it. Reading a version goes through package metadata: nothing here imports torch or
PyBullet. Where torch is loaded, the instruction set its CPU kernels use is kept too: two
machines that differ in it train to other weights from the same seed
(``docs/reproducing.md#what-is-bit-for-bit``).
"""

from __future__ import annotations

import platform
import subprocess
import sys
import time
from importlib import metadata
from pathlib import Path
from typing import Any

from perception.files import file_sha256

ROOT = Path(__file__).resolve().parents[1]
"""The project's folder, above ``harness/`` (a git checkout when installed from one)."""
PACKAGES = ("gva", "torch", "pybullet", "pin", "ruckig", "numpy")
"""The distributions whose versions change what a run computes."""


def provenance(inputs: dict[str, Path | None] | None = None) -> dict[str, Any]:
    """The provenance of the session now running; ``inputs``: files whose SHA-256 it records.

    Args:
        inputs: e.g. ``{"task_file": path, "checkpoint_weights": path}``; None values are
            recorded as None (e.g. a model without weights).

    """
    return {
        "versions": {name: _version(name) for name in PACKAGES},
        "python": platform.python_version(),
        "git": git_revision(),
        "sha256": {name: None if path is None else file_sha256(path)
                   for name, path in (inputs or {}).items()},
        "command": list(sys.argv),
        "platform": platform.platform(),
        "torch_cpu_capability": _torch_cpu_capability(),
        "started": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
    }


def git_revision() -> dict[str, Any] | None:
    """The checkout's commit and whether files differ from it; None outside a git checkout."""
    def git(*args: str) -> str | None:
        try:
            done = subprocess.run(["git", "-C", str(ROOT), *args], capture_output=True,
                                  text=True, timeout=10, check=False)
        except (OSError, subprocess.SubprocessError):
            return None
        return done.stdout.strip() if done.returncode == 0 else None

    commit = git("rev-parse", "HEAD")
    if commit is None:
        return None
    changed = git("status", "--porcelain", "--untracked-files=no")
    return {"commit": commit, "modified": bool(changed)}


def _torch_cpu_capability() -> str | None:
    """The instruction set of torch's CPU kernels (``AVX512``, ``AVX2``...); None: not loaded.

    Read only where the run loaded torch already (training, a checkpoint in the loop), so that
    an oracle run stays free of it.
    """
    torch = sys.modules.get("torch")
    return None if torch is None else str(torch.backends.cpu.get_cpu_capability())


def _version(name: str) -> str | None:
    try:
        return metadata.version(name)
    except metadata.PackageNotFoundError:
        return None
