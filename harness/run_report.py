"""The one progress bar of a run (:func:`cost_bar`) and what a run did (:class:`RunReport`)."""

from __future__ import annotations

import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Generic, Protocol, TypeVar

from tqdm import tqdm


def cost_bar(total: float, description: str, progress: bool) -> tqdm:
    """A bar over ``total`` estimated cost: percent done, elapsed, time left and a postfix.

    Measured in cost rather than in jobs, its time left stays honest while the long jobs,
    which run first, are still going.
    """
    return tqdm(total=total, disable=not progress or total <= 0, desc=description,
                file=sys.stderr,
                bar_format="{desc}: {percentage:3.0f}%|{bar}| [{elapsed}<{remaining}{postfix}]")


def duration(seconds: float) -> str:
    """``1 h 02 min`` or ``3 min 07 s``."""
    minutes, second = divmod(round(seconds), 60)
    hours, minute = divmod(minutes, 60)
    return f"{hours} h {minute:02d} min" if hours else f"{minute} min {second:02d} s"


class JobResult(Protocol):
    """A finished job, as a :class:`RunReport` counts it."""

    @property
    def failure(self) -> str | None:
        """None, or ``"Type: message"`` of the exception the job raised."""


Outcome = TypeVar("Outcome", bound=JobResult)
Skipped = TypeVar("Skipped")


@dataclass(frozen=True)
class RunReport(Generic[Outcome, Skipped]):
    """What a run of either table did: jobs computed and skipped, failures, outputs.

    ``wall_time_s`` covers the jobs, not drawing the reports after.
    """

    computed: tuple[Outcome, ...]
    skipped: tuple[Skipped, ...]  # finished earlier
    failed: tuple[dict[str, Any], ...]  # every failure the folder records, with its "error"
    wall_time_s: float
    outputs: tuple[Path, ...] = ()
    notes: tuple[str, ...] = ()
    table: str = ""  # a table to print with the summary (Table III's successes)

    def summary_lines(self, done: str, name: Callable[[dict[str, Any]], str]) -> list[str]:
        """Counts and wall time, then each failure (named by ``name``), then the notes."""
        failed_now = sum(outcome.failure is not None for outcome in self.computed)
        lines = [f"{len(self.computed)} {done} ({failed_now} failed), {len(self.skipped)} "
                 f"finished earlier and skipped; wall time {self.wall_time_s:.0f} s"]
        lines += [f"  FAILED {name(record)}: {record['error']}" for record in self.failed]
        return lines + [f"  note: {note}" for note in self.notes]

