"""Keeps PyBullet's C-level chatter ("pybullet build time ...", "argv[0]=") off the terminal.

Those lines are printed by C code straight to file descriptors 1 and 2, where they would mix
with a command's own output and progress bar. Python's ``sys.stdout`` cannot catch them, so the
descriptors themselves point at /dev/null for the moment it takes (an import, a connect).
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import sys
from collections.abc import Iterator

_libc = ctypes.CDLL(None)


@contextlib.contextmanager
def silenced_output() -> Iterator[None]:
    """Sends everything written to file descriptors 1 and 2 inside the block to /dev/null."""
    with contextlib.ExitStack() as stack:
        for stream in (sys.stdout, sys.stderr):
            stack.enter_context(_silenced(stream))
        yield


@contextlib.contextmanager
def _silenced(stream: object) -> Iterator[None]:
    try:
        fd = stream.fileno()  # type: ignore[attr-defined]
    except (AttributeError, OSError, ValueError):  # no real descriptor (e.g. captured)
        yield
        return
    stream.flush()  # type: ignore[attr-defined]
    saved = os.dup(fd)
    try:
        with open(os.devnull, "w") as devnull:
            os.dup2(devnull.fileno(), fd)
            try:
                yield
            finally:
                _libc.fflush(None)  # C stdio buffers, written before the descriptor returns
                os.dup2(saved, fd)
    finally:
        os.close(saved)


with silenced_output():
    import pybullet  # noqa: F401  (imported here, once, to swallow its build-time banner)
