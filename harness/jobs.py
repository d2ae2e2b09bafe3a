"""Jobs run side by side in "spawn" processes: trainings, dataset collections, pick trials.

::

    with JobPool(workers=2) as pool:
        pool.run(collect_one, collections, on_done=count)       # count returns None
        pool.run(train_one, cells, on_done=trials_of_the_cell)  # returns the jobs it releases

A run's jobs are a graph (a training needs its dataset, trials their checkpoint): ``on_done``
returns the jobs a result releases, and they run in the same call, as soon as a worker is free.
So a worker never waits for the slowest job of a phase while another job could start.

Torch and ``fork`` do not mix (a forked child inherits the parent's thread pools and locks), so
the pool spawns its workers; each runs torch on one thread, and one worker runs the jobs in this
process instead. Workers ignore Ctrl-C: the main process gets it and stops them.

This is the local executor, the default. :class:`Executor` names where a run's jobs go, and
:func:`harness.executors.open_pool` opens its pool: this one, or :class:`harness.ray_jobs.RayPool`,
which runs the same functions on the same jobs as Ray tasks.
"""

from __future__ import annotations

import heapq
import itertools
import multiprocessing
import os
import signal
import threading
import time
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass
from enum import Enum
from typing import Generic, Protocol, TypeVar

from tqdm import tqdm

from sim.errors import InvalidInputError

Job = TypeVar("Job")
Result = TypeVar("Result")


class ExecutorKind(Enum):
    """Where a run's jobs run."""

    LOCAL = "local"  # this machine's process pool (:class:`JobPool`)
    RAY = "ray"  # Ray tasks: a local Ray started for the run, or a cluster (:mod:`.ray_jobs`)


@dataclass(frozen=True)
class Executor:
    """Where a run's jobs run; not part of any result's identity (the records are the same).

    Args:
        kind: The local process pool (default: no cluster, no start-up) or Ray.
        ray_address: The Ray cluster to join (``ray://…`` or ``host:port``); None: the
            ``RAY_ADDRESS`` environment variable, else a local Ray started for the run with as
            many CPUs as the run's workers.

    """

    kind: ExecutorKind = ExecutorKind.LOCAL
    ray_address: str | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.kind, ExecutorKind):
            raise InvalidInputError("executor", self.kind,
                                    " or ".join(kind.value for kind in ExecutorKind))
        if self.ray_address is not None and (
                not isinstance(self.ray_address, str) or not self.ray_address.strip()):
            raise InvalidInputError("ray_address", self.ray_address,
                                    "None or a Ray address such as 'ray://head:10001'")
        if self.ray_address is not None and self.kind is not ExecutorKind.RAY:
            raise InvalidInputError("ray_address", self.ray_address,
                                    "only with the ray executor (--executor ray)")


LOCAL = Executor()
"""The default executor: this machine's process pool."""


@dataclass(frozen=True)
class JobResources:
    """What one job holds while it runs: Ray schedules by it (the local pool does not).

    Args:
        cpus: CPU cores (a training on two torch threads asks for two).
        gpus: GPUs (a training on a CUDA device asks for one).

    """

    cpus: float = 1.0
    gpus: float = 0.0

    @classmethod
    def training(cls, threads: int, device: str) -> JobResources:
        """What a training holds: its torch threads, and one GPU when it trains on CUDA."""
        return cls(cpus=float(threads), gpus=1.0 if device.startswith("cuda") else 0.0)


ONE_CPU = JobResources()
"""What most jobs hold: one core (a trial, a collection, a training on one thread)."""


Released = Callable[[Result], Iterable[Job] | None]
"""What a pool calls with each result: returns the jobs that result releases, or None."""


class Pool(Protocol):
    """What every executor's pool offers: run a function on each job, results here.

    A context manager: on exit after an exception (Ctrl-C included) no job of the run goes on.
    """

    def __enter__(self) -> Pool: ...

    def __exit__(self, kind: type[BaseException] | None, *_: object) -> None: ...

    def run(self, function: Callable[[Job], Result], jobs: Sequence[Job],
            on_done: Released[Result, Job],
            resources: Callable[[Job], JobResources] | None = None,
            order: Callable[[Job], float] | None = None) -> None:
        """Runs ``function`` on every job; ``on_done`` in this process, once per job.

        ``on_done`` returns the jobs its result releases (None: none), run in this call too;
        ``order`` ranks ready jobs, the smallest first (None: as given, then as released).
        """


class ReadyJobs(Generic[Job]):
    """The jobs ready to start, smallest ``order`` first, ties (and no order) as they came."""

    def __init__(self, jobs: Iterable[Job], order: Callable[[Job], float] | None) -> None:
        self._order = order
        self._count = itertools.count()
        self._heap: list[tuple[float, int, Job]] = []
        self.add(jobs)

    def add(self, jobs: Iterable[Job] | None) -> None:
        """Makes ``jobs`` ready (None: nothing)."""
        for job in jobs or ():
            rank = 0.0 if self._order is None else self._order(job)
            heapq.heappush(self._heap, (rank, next(self._count), job))

    def pop(self) -> Job:
        """Takes the first-ranked ready job."""
        return heapq.heappop(self._heap)[2]

    def __len__(self) -> int:
        return len(self._heap)


ORPHAN_CHECK_S = 1.0
"""How often a worker checks that the process that started it still runs [s]."""


def _start_worker() -> None:
    """A worker leaves Ctrl-C to the main process, which stops it; torch on one thread.

    A main process killed outright (``kill``, the OOM killer, a closed terminal) cannot stop
    its workers, and a worker left behind goes on with its job: a training that writes an
    outdated checkpoint into a run folder a later run is using. So each worker watches its
    parent and exits when it is gone.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    parent = os.getppid()

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(ORPHAN_CHECK_S)
        os._exit(1)  # the main process is gone: nobody will read this worker's result

    threading.Thread(target=watch, name="orphan-watch", daemon=True).start()
    os.environ["OMP_NUM_THREADS"] = "1"  # before torch is imported by the first cell
    # A worker shows no bar; tqdm's default lock is a multiprocessing semaphore, which a
    # stopped worker would leave to the resource tracker (and its warning at exit).
    tqdm.set_lock(threading.RLock())


class JobPool:
    """Runs jobs ``workers`` at a time; one pool of "spawn" processes serves every batch.

    One worker runs the jobs here, in order. More run in a process pool started at the first
    batch that needs it (a spawned worker imports torch once, then serves every later job),
    jobs handed out by rank as workers free up. On any exception, Ctrl-C included, the pool's
    processes are stopped, so no job outlives the run, and the exception goes on.
    """

    def __init__(self, workers: int) -> None:
        self.workers = workers
        self._executor: ProcessPoolExecutor | None = None

    def __enter__(self) -> JobPool:
        return self

    def __exit__(self, kind: type[BaseException] | None, *_: object) -> None:
        if self._executor is None:
            return
        if kind is not None:
            # No public way to stop running workers before Python 3.14's terminate_workers().
            for process in list(getattr(self._executor, "_processes", {}).values()):
                process.terminate()
        self._executor.shutdown(wait=True, cancel_futures=True)

    def run(self, function: Callable[[Job], Result], jobs: Sequence[Job],
            on_done: Released[Result, Job],
            resources: Callable[[Job], JobResources] | None = None,
            order: Callable[[Job], float] | None = None) -> None:
        """Runs ``function`` on every job and on every job a result releases; ``on_done`` here.

        At most ``workers`` jobs are handed out at a time, so a job released later still
        starts before a lower-ranked one that was ready earlier. ``resources`` is Ray's
        business: here each worker runs one job at a time, whatever the job asks, as
        ``workers`` was chosen for this machine.
        """
        ready = ReadyJobs(jobs, order)
        running: set[Future[Result]] = set()
        while ready or running:
            while ready and len(running) < self.workers:
                job = ready.pop()
                if self.workers == 1 or (not ready and not running and self._executor is None):
                    # No second job to run beside it: here, without starting processes.
                    ready.add(on_done(function(job)))
                    continue
                running.add(self._processes().submit(function, job))
            if running:
                finished, _ = wait(running, return_when=FIRST_COMPLETED)
                for future in finished:
                    running.remove(future)
                    ready.add(on_done(future.result()))

    def _processes(self) -> ProcessPoolExecutor:
        """The pool's spawned processes, started at the first job that needs them."""
        if self._executor is None:
            self._executor = ProcessPoolExecutor(
                max_workers=self.workers, mp_context=multiprocessing.get_context("spawn"),
                initializer=_start_worker)
        return self._executor
