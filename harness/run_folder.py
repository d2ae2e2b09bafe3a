"""A run's folder: the settings that identify it, and the lock that keeps one run in it.

``claim_run_folder`` accepts a folder only for the run it was made for (the message names what
differs); ``run_folder_lock`` refuses a second run on a folder at once. Trial runs, Table II and
Table III use both.
"""

from __future__ import annotations

import contextlib
import json
import os
import socket
import sys
import time
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any, NamedTuple

import filelock

from perception.files import atomic_write
from sim.errors import RunFolderError


def json_form(data: Mapping[str, Any]) -> dict[str, Any]:
    """``data`` as it reads back from JSON (tuples become lists), so stored and asked compare."""
    return json.loads(json.dumps(dict(data)))


def differences(stored: Mapping[str, Any], asked: Mapping[str, Any]) -> dict[str, Any]:
    """The keys whose values differ, as ``{key: (stored, asked)}``; nested dicts by their keys.

    A key inside a nested dict is named ``outer.inner``, so a message shows what changed
    (``model_config.temperature``) rather than two whole configurations.
    """
    found: dict[str, Any] = {}
    for key in sorted(set(stored) | set(asked), key=str):
        old, new = stored.get(key), asked.get(key)
        if isinstance(old, Mapping) and isinstance(new, Mapping):
            found |= {f"{key}.{inner}": pair for inner, pair in differences(old, new).items()}
        elif old != new:
            found[key] = (old, new)
    return found


def claim_run_folder(folder: Path, settings: Mapping[str, Any], name: str = "run.json",
                     provenance: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """Makes ``folder`` the home of the run ``settings`` identify; returns them in JSON form.

    A new folder gets ``folder/name`` holding the settings (written atomically); a folder that
    has one is accepted only if it holds the same settings. ``provenance``
    (:mod:`harness.provenance`) is appended to the file's ``provenance`` list, one entry per
    session that worked on the run; it is not part of what identifies the run.

    Raises:
        RunFolderError: The folder holds a different run (the message names what differs,
            stored vs asked), or its settings file is damaged.

    """
    folder.mkdir(parents=True, exist_ok=True)
    asked = json_form(settings)
    path = folder / name
    history: list[Any] = []
    if path.exists():
        stored = read_json_file(path, "use another --out")
        history = stored.pop(PROVENANCE_KEY, []) if isinstance(stored, dict) else []
        if stored != asked:
            raise RunFolderError(f"{folder} holds a different run ({differences(stored, asked)}"
                                 ", stored vs asked); use another --out or remove the folder")
    if provenance is not None or not path.exists():
        record = asked | {PROVENANCE_KEY: [*history, *([json_form(provenance)]
                                                         if provenance is not None else [])]}
        text = json.dumps(record, indent=2, sort_keys=True) + "\n"
        atomic_write(path, lambda temporary: temporary.write_text(text))
    return asked


def read_json_file(path: Path, remedy: str = "") -> Any:
    """The JSON in ``path``; a damaged file (not UTF-8, not JSON) is a RunFolderError naming it.

    ``remedy``: what the message tells the user to do about it (``"use another --out"``).
    """
    then = f"; {remedy}" if remedy else ""
    try:
        return json.loads(path.read_bytes().decode("utf-8"))
    except UnicodeDecodeError as error:
        raise RunFolderError(f"{path} is damaged (not UTF-8 text: byte {error.start} is "
                             f"{error.object[error.start]:#04x}){then}") from None
    except json.JSONDecodeError as error:
        raise RunFolderError(f"{path} is damaged ({error}){then}") from None


PROVENANCE_KEY = "provenance"
"""The key of a settings file's list of sessions (not part of the run's identity)."""


LOCK_FILE = ".gva.lock"
"""The lock a run holds on its folder for its whole life (``filelock``: an OS lock, released
by the OS when the process ends, however it ends)."""
HOLDER_FILE = ".gva.lock.holder"
"""Who holds the lock: process, host, start time and command, for the refusal's message."""


@contextlib.contextmanager
def run_folder_lock(folder: Path) -> Iterator[None]:
    """Holds ``folder``'s lock inside the block: one run per folder, at any time.

    A second run on the same folder, from this process or another, is refused at once rather
    than left to wait: two runs would write the same trials twice.

    Raises:
        RunFolderError: Another run holds the folder; the message says which, and what to do.

    """
    folder.mkdir(parents=True, exist_ok=True)
    lock = filelock.FileLock(folder / LOCK_FILE, timeout=0, thread_local=False)
    try:
        lock.acquire()
    except filelock.Timeout:
        holder = folder / HOLDER_FILE
        try:
            who = json.loads(holder.read_text())
            shown = (f"process {who['pid']} on {who['host']}, started "
                     f"{time.strftime('%Y-%m-%d %H:%M:%S', time.localtime(who['started']))}: "
                     f"{who['command']}")
        except (OSError, ValueError, KeyError, TypeError):
            shown = "another process"
        raise RunFolderError(f"{folder} is in use by another run ({shown}); wait until it "
                             "ends (then the same command resumes it) or use another --out"
                             ) from None
    try:
        who = {"pid": os.getpid(), "host": socket.gethostname(), "started": time.time(),
               "command": " ".join(sys.argv)}
        atomic_write(folder / HOLDER_FILE,
                     lambda temporary: temporary.write_text(json.dumps(who) + "\n"))
        yield
    finally:
        (folder / HOLDER_FILE).unlink(missing_ok=True)
        lock.release()


class RunStart(NamedTuple):
    """A run's start, as :func:`started_run` makes it: when, and its session's provenance."""

    started_s: float  # time.perf_counter() at the start: the run's wall time counts from it
    session: dict[str, Any]  # harness.provenance.provenance() of this session


@contextlib.contextmanager
def started_run(folder: Path, identity: Mapping[str, Any]) -> Iterator[RunStart]:
    """A run's hold on ``folder`` for the block: its lock, its session, its identity claimed.

    What every ``gva reproduce`` run does first: one run per folder (:func:`run_folder_lock`),
    this session's provenance recorded in the folder's ``run.json`` (:func:`claim_run_folder`,
    which refuses a folder holding another run).
    """
    from harness.provenance import provenance  # the same layer; kept out of import time

    with run_folder_lock(folder):
        start = RunStart(time.perf_counter(), provenance())
        claim_run_folder(folder, identity, provenance=start.session)
        yield start
