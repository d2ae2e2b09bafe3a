"""The job graph of ``gva reproduce real``: every unfinished job of every seed, as one graph.

A job starts as soon as what it needs is there (a training its task's demonstrations, trials
their checkpoint; a plug-in's trials nothing), so both cores stay busy across tasks and seeds.
A job that raises is recorded in ``OUT/errors/<job>.json`` and the run goes on; the jobs that
needed its output are left out and named. Finished work is found on disk before the run
starts, so a re-run skips it.
"""

from __future__ import annotations

from pathlib import Path

from experiments.table3.check_gate import admit, check_job
from experiments.table3.jobs import (
    GIF_S_PER_PICK,
    TRIAL_S_PER_PICK,
    CollectJob,
    GifJob,
    Job,
    JobOutcome,
    TrainJob,
    TrialsJob,
    collect_name,
    cost,
    gif_done,
    job_resources,
    run_job,
    task_targets,
    train_inputs,
    train_needs,
    trials_done,
)
from experiments.table3.layout import (
    error_file,
    gif_file,
    seed_folder,
    task_file,
    trained_file,
    trials_folder,
)
from experiments.table3.settings import PLAIN, SCENE, ReproduceRealSettings, TrialSet, Unit
from harness.executors import open_pool
from harness.run_files import dataset_present, read_json, refuse_other_settings
from harness.run_report import cost_bar
from harness.trial_log import log_identity, stored_identity
from sim.tasks.scene_sampling import SeedStream


def run_jobs(settings: ReproduceRealSettings, out: Path, progress: bool
             ) -> tuple[list[JobOutcome], list[str]]:
    """Runs every unfinished job of every seed as a job graph: (outcomes run, names skipped).

    A collection releases its task's trainings and a training its trial sets and GIF, so a
    worker starts the next job as soon as one is ready (trials of one task while the next
    task trains) rather than wait for the slowest job of a phase. Ready jobs start by the
    longest chain of work they lead to, so the slowest chain never starts last.
    """
    runs = [(settings.for_seed(seed), seed_folder(out, seed))
            for seed in settings.training_seeds]
    collects: list[CollectJob] = []
    trains: list[TrainJob] = []
    for run_settings, folder in runs:
        plugins = run_settings.plugins()
        units = [unit for unit in run_settings.units() if unit.model not in plugins]
        refuse_other_settings(
            [(str(path), read_json(path)["identity"], run_settings.train_identity(unit))
             for unit in units if (path := trained_file(folder, unit)).exists()],
            "checkpoint(s)")
        refuse_other_settings(  # a plug-in's identity: what gva trials records in run.json
            [(str(trials_folder(folder, s)), stored,
              log_identity(run_settings.trial_settings(folder, s).identity()))
             for s in run_settings.trial_sets() if s.unit.model in plugins
             and (stored := stored_identity(trials_folder(folder, s))) is not None],
            "plug-in trial set(s)")
        tasks = sorted({u.task for u in units}, key=[u.task for u in units].index)
        collects += [CollectJob(collect_name(t, run_settings.seed), t, run_settings, folder)
                     for t in tasks]
        if run_settings.randomised_scenes:  # beside the demonstrations, for trained units only
            collects += [CollectJob(collect_name(t, run_settings.seed, True), t, run_settings,
                                    folder, randomised=True) for t in tasks]
        trains += [TrainJob(f"train-{u.name}-s{run_settings.seed}", u, run_settings,
                            run_settings.train_identity(u), folder) for u in units]
    collects_todo = [j for j in collects if not _collected(j)]
    trains_todo = [j for j in trains if not trained_file(j.out, j.unit).exists()]
    for job in trains_todo:  # a check recorded of a checkpoint trained again is decided anew
        error_file(job.out, check_job(job.unit, job.settings.seed)).unlink(missing_ok=True)
    skipped = [j.name for j in collects if j not in collects_todo]
    skipped += [j.name for j in trains if j not in trains_todo]
    waiting = {j.name for j in collects_todo}
    trains_after: dict[str, list[TrainJob]] = {}  # a collection's name: the trainings it feeds
    pending: dict[str, set[str]] = {}  # a training's name: the collections it still waits for
    ready: list[Job] = list(collects_todo)
    for job in trains_todo:
        if waits := {name for name in train_needs(job) if name in waiting}:
            pending[job.name] = waits
            for name in waits:
                trains_after.setdefault(name, []).append(job)
        elif all(path.exists() for path in train_inputs(job)):
            ready.append(job)
    for run_settings, folder in runs:  # trials of the checkpoints that are there already
        todo, skipped_now = _trial_jobs(run_settings, folder)
        ready += todo
        skipped += skipped_now
    # Trials are not known to be finished before their checkpoint exists: estimate them as
    # to do unless their summary is there, and make the bar exact as they are released.
    later = {j.name: sum(_trials_estimate(j.settings, j.out, t)
                         for t in j.settings.trial_sets() if t.unit == j.unit)
             for j in trains_todo}
    total = sum(map(cost, ready)) + sum(cost(j) for j in trains_todo if j.name in pending) \
        + sum(later.values())
    computed: list[JobOutcome] = []
    by_name: dict[str, Job] = {job.name: job for job in ready}
    by_name |= {j.name: j for jobs in trains_after.values() for j in jobs}

    def chain(job: Job) -> float:
        """The estimated seconds of the longest chain of jobs that starts with ``job``."""
        if isinstance(job, CollectJob):
            return cost(job) + max((chain(j) for j in trains_after.get(job.name, ())),
                                   default=0.0)
        return cost(job) + (later.get(job.name, 0.0) if isinstance(job, TrainJob) else 0.0)

    with open_pool(settings.executor, settings.worker_count(), out) as pool, \
            cost_bar(total, "reproduce real", progress) as bar:
        def done(outcome: JobOutcome) -> list[Job]:
            computed.append(outcome)
            shown = "FAILED" if outcome.failure else outcome.result
            bar.set_postfix_str(f"{len(computed)} job(s) done; last {outcome.name}: "
                                f"{shown}", refresh=False)
            job = by_name[outcome.name]
            bar.update(cost(job))
            released: list[Job] = []
            if isinstance(job, CollectJob):
                for train in trains_after.get(job.name, []):
                    if train.name not in pending:
                        continue  # left out already: another collection it needs failed
                    if outcome.failure is not None:  # left out, and its trials
                        del pending[train.name]
                        bar.total -= cost(train) + later[train.name]
                        continue
                    pending[train.name].discard(job.name)
                    if not pending[train.name]:  # every dataset it trains on is there
                        del pending[train.name]
                        released.append(train)
            elif isinstance(job, TrainJob):
                if outcome.failure is None:
                    released, skipped_now = _trial_jobs(job.settings, job.out, job.unit)
                    skipped.extend(skipped_now)
                bar.total += sum(map(cost, released)) - later[job.name]  # the estimate, exact
            bar.refresh()
            by_name.update((j.name, j) for j in released)
            return released  # a failed job's error file names it; what needed it is left out

        pool.run(run_job, ready, done, job_resources, order=lambda job: -chain(job))
    return computed, skipped


def _collected(job: CollectJob) -> bool:
    """Whether a collection's dataset is there already (one of other settings is refused)."""
    settings, task = job.settings, str(task_file(job.out, job.task))
    if not job.randomised:
        return dataset_present(job.path, SCENE, task, settings.demos, settings.seed,
                               SeedStream.TRAIN, settings.approach_hz,
                               robot=settings.description())
    if not job.path.exists():
        return False
    wanted = settings.randomised_collect(task)
    return dataset_present(job.path, SCENE, task, wanted.size, wanted.seed, wanted.stream,
                           robot=settings.description(), labels=wanted.labels,
                           looks=wanted.looks)


def _trials_estimate(settings: ReproduceRealSettings, out: Path, trial_set: TrialSet) -> float:
    """A set's estimated cost, and its GIF's, unless they look finished already."""
    targets = task_targets(trial_set.unit.task)
    summary = trials_folder(out, trial_set) / "summary.json"
    estimate = 0.0 if summary.exists() else TRIAL_S_PER_PICK * settings.n * targets
    if trial_set.variant == PLAIN and settings.gif_trials and not gif_file(
            out, trial_set.unit).exists():
        estimate += GIF_S_PER_PICK * min(settings.gif_trials, settings.n) * targets
    return estimate


def _trial_jobs(settings: ReproduceRealSettings, out: Path, unit: Unit | None = None
                ) -> tuple[list[Job], list[str]]:
    """(trial and GIF jobs to run, names of those finished) of units with a checkpoint.

    ``unit``: only that unit's (its training just finished); None: every unit's. A checkpoint
    that failed its held-out check gets none unless the run uses such checkpoints
    (:func:`.check_gate.admit` records it as a failed cell).
    """
    todo: list[Job] = []
    skipped: list[str] = []
    plugins = settings.plugins()
    admitted: dict[Unit, bool] = {}
    for trial_set in settings.trial_sets():
        if unit not in (None, trial_set.unit) or not (
                trial_set.unit.model in plugins or trained_file(out, trial_set.unit).exists()):
            continue  # its training failed (its error file names it); a plug-in needs none
        if trial_set.unit not in admitted:
            admitted[trial_set.unit] = (trial_set.unit.model in plugins
                                        or admit(settings, out, trial_set.unit))
        if not admitted[trial_set.unit]:
            continue  # its checkpoint failed its held-out check: the cell is recorded failed
        trials = settings.trial_settings(out, trial_set)
        job = TrialsJob(f"trials-{trial_set.name}-s{settings.seed}", trial_set, trials, out)
        candidates: list[tuple[Job, bool]] = [(job, trials_done(job))]
        if trial_set.variant == PLAIN and settings.gif_trials:
            gif = GifJob(f"gif-{trial_set.unit.name}-s{settings.seed}", trial_set.unit, trials,
                         min(settings.gif_trials, settings.n), out)
            candidates.append((gif, gif_done(gif)))
        for candidate, finished in candidates:
            if finished:
                skipped.append(candidate.name)
            else:
                todo.append(candidate)
    return todo, skipped
