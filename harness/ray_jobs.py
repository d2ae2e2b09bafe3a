"""The Ray executor: a run's jobs as Ray tasks, on a local Ray or on a cluster.

The jobs and the functions are those of the local pool (:class:`harness.jobs.JobPool`); only where
they run changes. Every job still writes its files into the run folder itself, so on a cluster
that folder must be storage every node mounts at the same path (NFS, a parallel file system).
:func:`check_shared_folder` makes sure of it before the first job: a job's outputs (datasets,
checkpoints) are the next job's inputs, on whichever node it lands, which is why Ray Tune also
asks for shared or cloud storage on a cluster rather than copying results to the head node.
Why, and the measurements: ``docs/decisions/ray-executor.md``.

A job whose worker process or node dies is retried (:data:`JOB_RETRIES`); an exception a job
raises is its result and is not. Ctrl-C cancels this run's tasks, running ones included, and
what finished stays in the run folder.
"""

from __future__ import annotations

import logging
import os
import secrets
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from harness.jobs import ONE_CPU, Job, JobResources, ReadyJobs, Released, Result
from harness.provenance import git_revision
from sim.errors import InvalidInputError

try:
    import ray
    from ray.util.scheduling_strategies import NodeAffinitySchedulingStrategy
except ImportError as missing:  # an optional extra
    raise InvalidInputError(
        "executor", "ray", "with Ray installed: pip install -e '.[ray]'") from missing

JOB_RETRIES = 3
"""Times a job is run again when its worker process or its node dies (never on an exception
the job raised: that would only raise again)."""
LOCAL_OBJECT_STORE_BYTES = 256 * 2**20
"""The object store of a Ray started for one run: jobs return small results (a cell's error,
a trial's record), and Ray's default (30 % of memory) would take gigabytes from training."""
LOCAL_HEALTH_CHECK_FAILURES = 100
"""Missed health checks (3 s apart) before a Ray started for one run calls its own node dead.
Ray's default, 5, is for a cluster's network; on one busy machine a starved raylet misses 5
in 15 s, and Ray then ends itself and the run's process (docs/decisions/ray-executor.md)."""
LOCAL_SYSTEM_CONFIG = {"worker_niceness": 0,
                       "health_check_failure_threshold": LOCAL_HEALTH_CHECK_FAILURES}
"""A Ray started for a run gives its workers the local pool's priority (Ray's default niceness,
15, lets any other process on the machine starve them) and never gives up on its own node."""
WAIT_S = 0.5
"""The longest this process waits in Ray before it looks at signals again [s]."""
CHECK_TIMEOUT_S = 120.0
"""How long the shared-folder check waits for every node (a busy cluster may queue it)."""
ENV_ADDRESS = "RAY_ADDRESS"


class RayPool:
    """Runs jobs as Ray tasks; results come back here, in the order they finish.

    At its first job it joins the Ray this process already joined (a test's), else the cluster
    at ``address`` (or ``$RAY_ADDRESS``), else starts a local Ray of ``workers`` CPUs that it
    stops on exit.

    Args:
        workers: CPUs of a local Ray started for the run (a cluster has its own).
        address: A cluster to join; None: ``$RAY_ADDRESS``, else a local Ray.
        shared_folder: The run folder; every node must see it (checked at the first job).

    """

    def __init__(self, workers: int, address: str | None, shared_folder: Path) -> None:
        self.workers = workers
        self.address = address or os.environ.get(ENV_ADDRESS) or None
        self.shared_folder = Path(shared_folder)
        self._started = self._connected = False
        self._pending: set[Any] = set()  # this run's unfinished tasks

    def __enter__(self) -> RayPool:
        return self

    def __exit__(self, kind: type[BaseException] | None, *_: object) -> None:
        if kind is not None:  # Ctrl-C or a failed job: this run's tasks stop now
            for ref in self._pending:
                ray.cancel(ref, force=True)
        self._pending.clear()
        if self._started:
            ray.shutdown()
            self._started = False

    def _connect(self) -> None:
        """Joins or starts Ray, then checks the run folder (at the first job only)."""
        if self._connected:
            return
        if not ray.is_initialized():
            if self.address is not None:
                ray.init(address=self.address, logging_level=logging.ERROR)
            else:
                start_local_ray(self.workers)
                self._started = True
        check_shared_folder(self.shared_folder)
        self._connected = True

    def run(self, function: Callable[[Job], Result], jobs: Sequence[Job],
            on_done: Released[Result, Job],
            resources: Callable[[Job], JobResources] | None = None,
            order: Callable[[Job], float] | None = None) -> None:
        """Runs ``function`` on every job, and every job a result releases, as Ray tasks.

        Every ready job is submitted at once, by rank (Ray's scheduler places them); a job's
        exception is raised here (after its pool's tasks are cancelled); a job lost with its
        worker or node is run again, up to :data:`JOB_RETRIES` times.
        """
        ready = ReadyJobs(jobs, order)
        if not ready:
            return
        self._connect()
        task = ray.remote(function)
        while ready or self._pending:
            while ready:
                job = ready.pop()
                need = resources(job) if resources is not None else ONE_CPU
                ref = task.options(num_cpus=need.cpus, num_gpus=need.gpus,
                                   max_retries=JOB_RETRIES, retry_exceptions=False,
                                   name=getattr(job, "name", None)).remote(job)
                self._pending.add(ref)
            # A bounded wait returns to Python each time, where a pending Ctrl-C is raised.
            finished, _ = ray.wait(list(self._pending), num_returns=1, timeout=WAIT_S)
            for ref in finished:
                self._pending.remove(ref)  # finished, whatever get says: never cancelled
                result = ray.get(ref)  # a job's exception: raised, the rest cancelled on exit
                ready.add(on_done(result))


def start_local_ray(cpus: int) -> None:
    """Starts a Ray on this machine for one run: ``cpus`` CPUs, its GPUs, no dashboard."""
    logging.getLogger("ray").setLevel(logging.ERROR)  # start-up chatter, not results
    ray.init(num_cpus=cpus, include_dashboard=False,
             object_store_memory=LOCAL_OBJECT_STORE_BYTES, logging_level=logging.ERROR,
             _system_config=LOCAL_SYSTEM_CONFIG)


def _sees(path: str, token: str) -> tuple[bool, dict[str, Any] | None]:
    """On one node: whether it reads ``token`` at ``path``, and its code's git revision."""
    try:
        seen = Path(path).read_text() == token
    except OSError:
        seen = False
    return seen, git_revision()


def check_shared_folder(folder: Path) -> None:
    """Refuses a run whose folder some node cannot see, or whose nodes run other code.

    Writes a random token into ``folder`` and has a zero-CPU task pinned to each live node read
    it. A node that joins later is not checked: give a cluster its nodes before the run.

    Raises:
        InvalidInputError: Names the nodes that do not see the folder, or run another commit.

    """
    folder.mkdir(parents=True, exist_ok=True)
    token = secrets.token_hex(16)
    probe = folder / f".gva-shared-check-{token[:8]}"
    probe.write_text(token)
    try:
        nodes = [node for node in ray.nodes() if node.get("Alive")]
        look = ray.remote(_sees)
        refs = [look.options(num_cpus=0, scheduling_strategy=NodeAffinitySchedulingStrategy(
            node["NodeID"], soft=False)).remote(str(probe.resolve()), token) for node in nodes]
        answers = ray.get(refs, timeout=CHECK_TIMEOUT_S)
    finally:
        probe.unlink(missing_ok=True)
    refusal = refuse_nodes(folder, nodes, answers, _commit(git_revision()))
    if refusal is not None:
        raise refusal


def refuse_nodes(folder: Path, nodes: list[dict[str, Any]],
                 answers: list[tuple[bool, dict[str, Any] | None]], here: str | None
                 ) -> InvalidInputError | None:
    """The error for nodes that do not see ``folder`` or run a commit other than ``here``."""
    def named(node: dict[str, Any]) -> str:
        return str(node.get("NodeManagerAddress") or node["NodeID"])

    blind = [named(node) for node, (seen, _) in zip(nodes, answers, strict=True) if not seen]
    if blind:
        return InvalidInputError(
            "out", str(folder), f"a folder every Ray node sees at the same path; node(s) "
            f"{', '.join(blind)} do not (mount shared storage there: docs/cluster.md)")
    other = [named(node) for node, (_, revision) in zip(nodes, answers, strict=True)
             if _commit(revision) != here]
    if other:
        return InvalidInputError(
            "executor", "ray", f"nodes running this run's code (commit {here}); node(s) "
            f"{', '.join(other)} run another: install the same revision on every node")
    return None


def _commit(revision: dict[str, Any] | None) -> str | None:
    return None if revision is None else revision["commit"]
