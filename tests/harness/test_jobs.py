"""The job pool: jobs side by side, results in this process, no worker outliving its run."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from harness.jobs import JobPool
from sim.errors import InvalidInputError


def _square(value: int) -> int:
    return value * value


def test_jobs_run_side_by_side_and_every_result_comes_back():
    results: list[int] = []
    with JobPool(2) as pool:
        pool.run(_square, [1, 2, 3, 4], results.append)
    assert sorted(results) == [1, 4, 9, 16]


def _echo(value: int) -> int:
    return value


@pytest.mark.parametrize("order", [None, lambda job: job], ids=["as-given", "ranked"])
def test_a_result_releases_jobs_that_run_in_the_same_call_by_rank(order):
    """A job graph: each job below 10 releases ten times itself once it is done."""
    seen: list[int] = []

    def done(job: int) -> list[int] | None:
        seen.append(job)
        return [job * 10] if job < 10 else None

    with JobPool(1) as pool:
        pool.run(_echo, [5, 1, 3], done, order=order)
    assert seen == ([5, 1, 3, 50, 10, 30] if order is None else [1, 3, 5, 10, 30, 50])


def test_released_jobs_run_on_the_workers_after_the_job_that_released_them():
    seen: list[int] = []

    def done(job: int) -> list[int] | None:
        seen.append(job)
        return [job * 10, job * 10 + 1] if job < 10 else None

    with JobPool(2) as pool:
        pool.run(_echo, [1, 2, 3], done)
    assert sorted(seen) == [1, 2, 3, 10, 11, 20, 21, 30, 31]
    assert all(seen.index(job) < seen.index(job * 10) for job in (1, 2, 3))


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    with open(f"/proc/{pid}/stat") as stat:  # a zombie has exited; its parent reaps it
        return stat.read().split()[2] != "Z"


def test_workers_exit_when_the_main_process_is_killed(tmp_path: Path):
    """A run killed outright (no Ctrl-C, no cleanup) leaves no worker going on with its job."""
    pids = tmp_path / "pids"
    script = textwrap.dedent(f"""
        import os, time
        from harness.jobs import JobPool

        def job(_):
            with open({str(pids)!r}, "a") as handle:
                handle.write(f"{{os.getpid()}}\\n")
            time.sleep(120)

        if __name__ == "__main__":
            with JobPool(2) as pool:
                pool.run(job, [0, 1], print)
    """)
    (tmp_path / "run.py").write_text(script)
    main = subprocess.Popen([sys.executable, str(tmp_path / "run.py")], cwd=Path.cwd(),
                            env=os.environ | {"PYTHONPATH": str(Path.cwd())})
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and (
            not pids.exists() or len(pids.read_text().split()) < 2):
        time.sleep(0.2)
    workers = [int(pid) for pid in pids.read_text().split()]
    assert len(workers) == 2 and all(_alive(pid) for pid in workers)
    main.send_signal(signal.SIGKILL)
    main.wait()
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline and any(_alive(pid) for pid in workers):
        time.sleep(0.2)
    assert not any(_alive(pid) for pid in workers)


def _refuse(value: int) -> int:
    raise InvalidInputError("value", value, "an even number")


def test_a_workers_bad_input_error_comes_back_whole():
    """Raised in a worker, pickled home: the same type, field and message (not a pickling error)."""
    with pytest.raises(InvalidInputError, match="is not allowed: an even number") as raised, \
            JobPool(2) as pool:
        pool.run(_refuse, [3, 5], print)
    assert raised.value.field == "value"
