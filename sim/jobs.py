"""Jobs run side by side in "spawn" processes: trainings, dataset collections, pick trials.

::

    with JobPool(workers=2) as pool:
        pool.run(collect_one, collections, on_done=lambda result: bar.update())
        pool.run(train_one, cells, on_done=keep)

Torch and ``fork`` do not mix (a forked child inherits the parent's thread pools and locks), so
the pool spawns its workers; each runs torch on one thread, and one worker runs the jobs in this
process instead. Workers ignore Ctrl-C: the main process gets it and stops them.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import threading
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from typing import TypeVar

from tqdm import tqdm

Job = TypeVar("Job")
Result = TypeVar("Result")


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
    jobs handed out in order. On any exception, Ctrl-C included, the pool's processes are
    stopped, so no job outlives the run, and the exception goes on.
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
            on_done: Callable[[Result], None]) -> None:
        """Runs ``function`` on every job; ``on_done`` here, as each finishes."""
        if self.workers == 1 or (len(jobs) <= 1 and self._executor is None):
            for job in jobs:
                on_done(function(job))
            return
        if self._executor is None:
            self._executor = ProcessPoolExecutor(
                max_workers=self.workers, mp_context=multiprocessing.get_context("spawn"),
                initializer=_start_worker)
        futures = [self._executor.submit(function, job) for job in jobs]
        for future in as_completed(futures):
            on_done(future.result())
