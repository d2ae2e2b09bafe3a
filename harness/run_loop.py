"""Runs of pick trials: the resumable loop, side by side or not, and the summary.

Trial ``i`` of a run with seed ``s`` runs test scene ``i`` of seed ``s`` (see
:mod:`sim.trials.trial_scenes`), so the same seed gives the same trials, and no trial runs on a
scene a model was trained on. Every finished trial is appended to ``trials.jsonl`` before the
next one starts; running the same command again resumes where an interrupted run stopped. What
a run is and how its model loads: :mod:`harness.inputs.trial_settings`.

A model that misbehaves costs its trial, never the run: each pick records it as
``perception_failed`` (:mod:`sim.trials.trial_runner`). Only ``KeyboardInterrupt`` (Ctrl-C) and
``SystemExit`` stop a run; :class:`RunStopped` then carries the summary of what finished, and
the same command resumes it.
"""

from __future__ import annotations

import contextlib
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tqdm import tqdm

from harness.executors import open_pool
from harness.inputs.trial_settings import TrialSettings, held_out_check, load_trial_model
from harness.jobs import LOCAL, Executor, ExecutorKind
from harness.provenance import provenance
from harness.run_folder import run_folder_lock
from harness.trial_log import TrialLog
from harness.trial_summary import TrialSummary
from perception.files import atomic_write
from sim.errors import InvalidInputError
from sim.tasks.scene_sampling import Scene
from sim.trials.records import TrialRecord
from sim.trials.trial_models import TrialModel, torch_threads
from sim.trials.trial_runner import TrialRunner
from sim.trials.trial_scenes import trial_scene

TRIAL_WORKERS = 1
"""Processes a run of trials uses by default: one (a trial is one image and one plan at a
time; ``--workers`` runs several side by side)."""


class RunStopped(BaseException):
    """A run stopped before its last trial by Ctrl-C or ``SystemExit``; what finished is kept.

    A ``BaseException``, as the two it stands for: no ``except Exception`` swallows it.

    Args:
        summary: The trials that finished, as ``summary.json`` holds them.
        cause: The ``KeyboardInterrupt`` or ``SystemExit`` that stopped the run.

    """

    def __init__(self, summary: TrialSummary, cause: BaseException) -> None:
        self.summary, self.cause = summary, cause
        why = "interrupted" if isinstance(cause, KeyboardInterrupt) else \
            f"the model raised SystemExit({getattr(cause, 'code', None)!r})"
        super().__init__(f"{why} after {summary.n} finished trials")


def run_trials(
    settings: TrialSettings, out_dir: str | Path, progress: bool = True,
    workers: int = TRIAL_WORKERS, executor: Executor = LOCAL,
) -> TrialSummary:
    """Runs (or resumes) ``settings.n`` trials into ``out_dir``; writes ``summary.json``.

    The folder is locked for the run (:func:`~harness.run_folder.run_folder_lock`). With
    ``workers`` > 1 the trials run side by side in that many processes (:mod:`harness.jobs`), or
    with the Ray executor as Ray tasks, one per trial (:mod:`harness.ray_jobs`); this process
    appends each record as it comes. Every trial starts from a rebuilt world, so the records
    are those of one process, in the order they finish.

    Raises:
        RunStopped: Ctrl-C or ``SystemExit`` stopped the run; ``summary.json`` holds what
            finished, and the same call resumes.
        RunFolderError: Another run holds the folder, or it holds a different run.

    """
    if not isinstance(workers, int) or isinstance(workers, bool) or workers < 1:
        raise InvalidInputError("workers", workers, "an integer >= 1")
    out = Path(out_dir)
    # Every scene is drawn first (a millisecond each): a task that random placement cannot fill
    # is refused, naming its packing, before a model loads, a run folder is made or a trial runs.
    task = settings.task_spec  # read once: the property parses the task file
    scenes = [trial_scene(task, settings.seed, index) for index in range(settings.n)]
    model = load_trial_model(settings)  # a refused model leaves no run folder behind
    with run_folder_lock(out):
        session = provenance(settings.inputs())
        log = TrialLog(out, settings.identity(), session)
        todo = [i for i in range(settings.n) if not log.done(i)]
        try:
            _run_todo(settings, model, log, [scenes[i] for i in todo], progress,
                      workers, executor)
        except (KeyboardInterrupt, SystemExit) as stop:
            raise RunStopped(_write_summary(settings, log, out, session), stop) from stop
        return _write_summary(settings, log, out, session)


def _run_todo(settings: TrialSettings, model: TrialModel, log: TrialLog, todo: list[Scene],
              progress: bool, workers: int, executor: Executor) -> None:
    """Runs a trial on each scene of ``todo``, appending each to ``log`` as it finishes."""
    if not todo:
        return
    task = settings.task_spec
    with tqdm(total=settings.n, initial=settings.n - len(todo), disable=not progress,
              desc=f"{model.label} / {task.name}", unit="trial") as bar:
        def done(record: TrialRecord) -> None:
            log.append(record)
            summary = log.summary(settings.n)
            bar.set_postfix_str(f"{summary.successes}/{summary.n} ok")
            bar.update()

        if executor.kind is ExecutorKind.RAY or (workers > 1 and len(todo) > 1):
            with open_pool(executor, min(workers, len(todo)), log.folder) as pool:
                pool.run(run_trial_job, [TrialJob(settings, s.index) for s in todo], done)
            return
        threads = torch_threads(1) if model.one_torch_thread else contextlib.nullcontext()
        with threads, TrialRunner(task, model.factory, settings.settle_s, settings.execution,
                                  obstacles=settings.obstacles, loop=settings.loop,
                                  robot=settings.description()) as runner:
            for scene in todo:
                done(runner.run(scene, scene.index, settings.seed, settings.model))


@dataclass(frozen=True)
class TrialJob:
    """One trial of a run, as a worker process runs it."""

    settings: TrialSettings
    index: int

    @property
    def name(self) -> str:
        """``trial-7``: the job's name in Ray's task list."""
        return f"trial-{self.index}"


_WORKER_RUNNER: list[tuple[TrialSettings, TrialRunner]] = []
"""The runner a worker process keeps for its run (built at its first trial)."""


def run_trial_job(job: TrialJob) -> TrialRecord:
    """Runs one trial in a worker process (:mod:`harness.jobs` limits it to one torch thread)."""
    settings = job.settings
    if not _WORKER_RUNNER or _WORKER_RUNNER[0][0] != settings:
        for _, old in _WORKER_RUNNER:
            old.close()
        model = load_trial_model(settings)
        _WORKER_RUNNER[:] = [(settings, TrialRunner(
            settings.task_spec, model.factory, settings.settle_s, settings.execution,
            obstacles=settings.obstacles, loop=settings.loop, robot=settings.description()))]
    runner = _WORKER_RUNNER[0][1]
    scene = trial_scene(runner.task, settings.seed, job.index)
    return runner.run(scene, job.index, settings.seed, settings.model)


def _write_summary(settings: TrialSettings, log: TrialLog, out: Path,
                   session: dict[str, Any]) -> TrialSummary:
    """Writes ``summary.json`` of the trials ``log`` holds; their summary."""
    summary = log.summary(settings.n)
    check = held_out_check(settings)
    data = {"settings": settings.identity() | {"n": settings.n}} | summary.to_dict() | {
        "held_out_check": None if check is None else check.to_json(), "provenance": session}
    text = json.dumps(data, indent=2, sort_keys=True) + "\n"
    atomic_write(out / "summary.json", lambda temporary: temporary.write_text(text))
    return summary

