"""Opens the pool of the executor a run asked for: the local process pool, or Ray.

Ray is an optional extra, imported only when a run asks for it, so a plain install (and every
run on one machine) never loads it.
"""

from __future__ import annotations

from pathlib import Path

from harness.jobs import Executor, ExecutorKind, JobPool, Pool


def open_pool(executor: Executor, workers: int, out: Path) -> Pool:
    """The pool of ``executor``, to use as a context manager around a run's jobs.

    Args:
        executor: Where the jobs run.
        workers: Processes of the local pool, or CPUs of a local Ray started for the run.
        out: The run folder; under Ray every node must see it (checked at the first job).

    """
    if executor.kind is ExecutorKind.LOCAL:
        return JobPool(workers)
    from harness.ray_jobs import RayPool  # the optional extra, imported only when asked for

    return RayPool(workers, executor.ray_address, out)
