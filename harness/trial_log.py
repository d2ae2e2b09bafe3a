"""A run's trials, kept in an append-only JSON-lines file that survives crashes.

Each finished trial is one line of ``trials.jsonl`` (:class:`sim.trials.records.TrialRecord`),
flushed and fsynced before the next trial starts; ``run.json`` beside it holds the run's
settings. Opening the same folder again resumes: finished trials are kept and skipped, a
half-written last line (a crash mid-write) is dropped, and a folder that holds a different run
is refused rather than mixed.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

from harness.run_folder import PROVENANCE_KEY, claim_run_folder, json_form, read_json_file
from harness.trial_summary import TrialSummary
from sim.errors import RunFolderError
from sim.trials.records import RECORD_FORMAT_VERSION, TrialRecord, record_lines, record_of_line


class TrialLog:
    """The ``trials.jsonl`` + ``run.json`` pair of a run folder; see the module docstring.

    Args:
        folder: The run folder (created if missing).
        settings: What identifies the run (task, model, seed, ...). Resuming a folder whose
            ``run.json`` holds other settings raises :class:`RunFolderError`.
        provenance: This session's provenance, appended to ``run.json``'s list.

    """

    def __init__(self, folder: str | Path, settings: Mapping[str, Any],
                 provenance: Mapping[str, Any] | None = None) -> None:
        self.folder = Path(folder)
        self.path = self.folder / "trials.jsonl"
        self.settings = claim_run_folder(self.folder, log_identity(settings),
                                         provenance=provenance)
        self.records: dict[int, TrialRecord] = dict(self._read())

    def _read(self) -> Iterator[tuple[int, TrialRecord]]:
        if not self.path.exists():
            return
        lines = record_lines(self.path)
        kept: list[bytes] = []
        for number, line in enumerate(lines, start=1):
            try:
                record = record_of_line(line)
            except (json.JSONDecodeError, TypeError, ValueError, KeyError) as error:
                if number == len(lines):  # a crash mid-write: drop the partial last line
                    self.path.write_bytes(b"".join(k + b"\n" for k in kept))
                    return
                raise RunFolderError(f"{self.path} line {number} is damaged: {error}") from None
            kept.append(line)
            yield record.index, record

    def done(self, index: int) -> bool:
        """Whether trial ``index`` already finished."""
        return index in self.records

    def append(self, record: TrialRecord) -> None:
        """Appends one finished trial and forces it to disk before returning."""
        with self.path.open("a", encoding="utf-8") as handle:
            handle.write(record.to_json() + "\n")
            handle.flush()
            os.fsync(handle.fileno())
        self.records[record.index] = record

    def summary(self, n: int) -> TrialSummary:
        """The summary of trials ``0 .. n-1``."""
        return TrialSummary.of([self.records[i] for i in range(n) if i in self.records])


def log_identity(settings: Mapping[str, Any]) -> dict[str, Any]:
    """What a trial folder's ``run.json`` holds to identify the run ``settings`` identify."""
    return json_form({"format_version": RECORD_FORMAT_VERSION, **settings})


def stored_identity(folder: Path) -> dict[str, Any] | None:
    """The identity ``folder``'s ``run.json`` holds (its sessions left out); None: none yet.

    With :func:`log_identity`, a caller can refuse a folder begun with other settings before
    any trial runs (:func:`harness.run_files.refuse_other_settings`), not when it opens it.
    """
    path = folder / "run.json"
    if not path.exists():
        return None
    stored = read_json_file(path, "use another --out")
    return {key: value for key, value in stored.items() if key != PROVENANCE_KEY}
