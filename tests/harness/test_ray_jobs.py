"""The Ray executor: the local pool's jobs as Ray tasks, every result once, lost workers retried.

The tests share one local Ray of 2 CPUs (``local_ray``); the job functions travel by value, as
this module is not importable on Ray's workers.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest
import ray
from gva_cli import gva

from harness.executors import open_pool
from harness.jobs import Executor, ExecutorKind, JobPool, JobResources
from harness.ray_jobs import RayPool, refuse_nodes
from sim.errors import InvalidInputError

pytestmark = pytest.mark.ray  # make test runs these alone, after the rest
ray.cloudpickle.register_pickle_by_value(sys.modules[__name__])
RAY = Executor(ExecutorKind.RAY)


def _square(value: int) -> int:
    return value * value


def test_every_result_comes_back_once(local_ray, tmp_path):
    results: list[int] = []
    with open_pool(RAY, 2, tmp_path) as pool:
        pool.run(_square, list(range(10)), results.append)
        pool.run(_square, [], results.append)  # an empty batch is no task
    assert sorted(results) == [v * v for v in range(10)]
    assert not list(tmp_path.glob(".gva-shared-check-*"))  # the folder check cleans up


def test_a_result_releases_jobs_that_run_as_ray_tasks_too(local_ray, tmp_path):
    """The local pool's job graph, on Ray: released jobs run in the same call."""
    seen: list[int] = []

    def done(square: int) -> list[int] | None:
        seen.append(square)
        return [square] if square < 10 else None  # 2 -> 4 -> 16, 3 -> 9 -> 81

    with open_pool(RAY, 2, tmp_path) as pool:
        pool.run(_square, [2, 3], done)
    assert sorted(seen) == [4, 9, 16, 81]


def _die_once(job: tuple[int, str]) -> tuple[int, int]:
    """Kills its own worker process the first time it runs, as a lost node would."""
    value, marks = job
    mark = Path(marks) / f"{value}.ran"
    if not mark.exists():
        mark.write_text(str(os.getpid()))
        os.kill(os.getpid(), signal.SIGKILL)
    return value, os.getpid()


def test_a_job_whose_worker_is_killed_runs_again_and_comes_back_once(local_ray, tmp_path):
    results: list[tuple[int, int]] = []
    with RayPool(2, None, tmp_path) as pool:
        pool.run(_die_once, [(v, str(tmp_path)) for v in range(4)], results.append)
    assert sorted(value for value, _ in results) == [0, 1, 2, 3]  # each once
    for value, pid in results:  # each finished in a worker other than the one killed
        assert pid != int((tmp_path / f"{value}.ran").read_text())


def _fails(value: int) -> int:
    raise InvalidInputError("value", value, "something else")


def test_a_jobs_exception_is_raised_here_with_its_own_type(local_ray, tmp_path, monkeypatch):
    cancelled: list[object] = []
    monkeypatch.setattr(ray, "cancel", lambda ref, **_: cancelled.append(ref))
    with pytest.raises(InvalidInputError, match="value = 3"), RayPool(2, None, tmp_path) as pool:
        pool.run(_fails, [3], print)
    assert cancelled == []  # the failed task had finished: force-cancelling one aborted the
    # driver once ("Tried to complete task that was not pending", Ray 2.60)


def _cpus(_: int) -> float:
    return ray.get_runtime_context().get_assigned_resources().get("CPU", 0.0)


def test_a_job_holds_the_cpus_it_asks_for(local_ray, tmp_path):
    held: list[float] = []
    with RayPool(2, None, tmp_path) as pool:
        pool.run(_cpus, [0, 1], held.append, lambda job: JobResources(cpus=1.0 + job))
    assert sorted(held) == [1.0, 2.0]


def test_nodes_that_do_not_see_the_folder_or_run_other_code_are_named():
    nodes = [{"NodeID": "a", "NodeManagerAddress": "10.0.0.1"},
             {"NodeID": "b", "NodeManagerAddress": "10.0.0.2"}]
    here = {"commit": "abc", "modified": False}
    assert refuse_nodes(Path("/runs/x"), nodes, [(True, here), (True, here)], "abc") is None
    blind = refuse_nodes(Path("/runs/x"), nodes, [(True, here), (False, here)], "abc")
    assert blind is not None and "node(s) 10.0.0.2 do not" in str(blind)
    assert str(blind).startswith("out = '/runs/x' is not allowed")
    other = refuse_nodes(Path("/runs/x"), nodes, [(True, {"commit": "def"}), (True, here)],
                         "abc")
    assert other is not None and "10.0.0.1 run another" in str(other)


def test_an_address_without_the_ray_executor_is_refused(tmp_path):
    with pytest.raises(InvalidInputError, match="ray_address"):
        Executor(ExecutorKind.LOCAL, "ray://head:10001")
    status, _, stderr = gva("trials", "--out", tmp_path / "t", "--ray-address", "x:1")
    assert status == 2 and "only with the ray executor" in stderr
    assert isinstance(open_pool(Executor(), 2, tmp_path), JobPool)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    with open(f"/proc/{pid}/stat") as stat:  # a zombie has exited
        return stat.read().split()[2] != "Z"


def test_ctrl_c_stops_the_runs_tasks_and_keeps_what_finished(tmp_path):
    """A driver of its own (its own local Ray): Ctrl-C while two jobs run and one finished."""
    script = textwrap.dedent(f"""
        import os, signal, time
        from pathlib import Path
        from harness.executors import open_pool
        from harness.jobs import Executor, ExecutorKind

        HERE = Path({str(tmp_path)!r})

        def job(value):
            Path(HERE, f"{{value}}.pid").write_text(str(os.getpid()))
            if value:
                time.sleep(300)
            return value

        if __name__ == "__main__":
            # As at a terminal: a shell's background job (CI's, say) starts with Ctrl-C
            # ignored, and Python then keeps it ignored.
            signal.signal(signal.SIGINT, signal.default_int_handler)
            try:
                with open_pool(Executor(ExecutorKind.RAY), 2, HERE) as pool:
                    pool.run(job, [0, 1, 2], lambda v: Path(HERE, f"{{v}}.done").touch())
            except KeyboardInterrupt:
                Path(HERE, "stopped").touch()
    """)
    (tmp_path / "driver.py").write_text(script)
    log = (tmp_path / "driver.log").open("w")
    driver = subprocess.Popen([sys.executable, str(tmp_path / "driver.py")], cwd=tmp_path,
                              stdout=log, stderr=subprocess.STDOUT)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and not (
            (tmp_path / "0.done").exists() and (tmp_path / "1.pid").exists()
            and (tmp_path / "2.pid").exists()):
        time.sleep(0.2)
    workers = [int((tmp_path / f"{v}.pid").read_text()) for v in (1, 2)]
    assert all(_alive(pid) for pid in workers)
    driver.send_signal(signal.SIGINT)
    try:
        status = driver.wait(timeout=60)
    finally:
        driver.kill()
        log.close()
    assert status == 0 and (tmp_path / "stopped").exists(), (tmp_path / "driver.log").read_text()
    deadline = time.monotonic() + 20
    while time.monotonic() < deadline and any(_alive(pid) for pid in workers):
        time.sleep(0.2)
    assert not any(_alive(pid) for pid in workers)
    assert (tmp_path / "0.done").exists() and not (tmp_path / "1.done").exists()


def test_a_training_asks_for_its_threads_and_a_gpu_only_on_cuda():
    assert JobResources.training(2, "cpu") == JobResources(cpus=2.0, gpus=0.0)
    assert JobResources.training(1, "cuda:0") == JobResources(cpus=1.0, gpus=1.0)


def test_the_cluster_address_comes_from_the_option_or_the_environment(monkeypatch, tmp_path):
    monkeypatch.setenv("RAY_ADDRESS", "head:6379")
    assert RayPool(2, None, tmp_path).address == "head:6379"
    assert RayPool(2, "other:6379", tmp_path).address == "other:6379"
    monkeypatch.delenv("RAY_ADDRESS")
    assert RayPool(2, None, tmp_path).address is None  # a local Ray for the run
