"""The datasets of ``gva reproduce sim``: training sets and test sets in ``OUT/datasets/``.

Training sets: for each task and training seed, scenes ``0 .. size - 1`` of the seed's TRAIN
stream. Scene ``i`` depends on the seed, the stream and ``i`` alone, so each task and seed is
collected once at its largest size and the smaller sets are written as its prefixes, byte for
byte what ``gva collect`` writes for them. Test sets: for each task, the first ``test_scenes``
scenes of the TEST stream of the first seed. A file already there is reused after checking its
metadata (scene, task, size, seed, stream and the task's definition); one that holds another
dataset is refused, never overwritten.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from experiments.runs import dataset_present

if TYPE_CHECKING:  # sim.scene imports pinocchio: not for `gva --help`
    from sim.scene import SeedStream

SCENE = "paper-sim"
"""The paper's simulator scene, Table II's."""
SCENES = ("paper-sim", "yumi")
"""The scenes a sweep can run on (yumi: demonstrations, offline)."""


def dataset_path(out: Path, task: str, stream: SeedStream, size: int, seed: int) -> Path:
    """Where a training (TRAIN) or test (TEST) dataset of a run folder lives."""
    return out / "datasets" / f"{task}-{stream.name.lower()}-{size}-s{seed}.gva"


@dataclass(frozen=True)
class DatasetJob:
    """Datasets of one task and seed in one stream: ``sizes`` scenes each, all one prefix."""

    task: str
    seed: int
    stream: SeedStream
    sizes: tuple[int, ...]
    out: Path
    scene: str = SCENE


def collect_datasets(job: DatasetJob) -> DatasetJob:
    """Collects the largest of ``job.sizes`` once and writes the smaller sets as its prefixes."""
    from perception.dataset_file import save_dataset
    from sim.collect import CollectSettings, collect

    largest = max(job.sizes)
    settings = CollectSettings(job.scene, job.task, largest, job.seed, job.stream)
    full = collect(settings, dataset_path(job.out, job.task, job.stream, largest, job.seed),
                   progress=False)
    for size in job.sizes:
        if size != largest:
            save_dataset(full.first_scenes(size),
                         dataset_path(job.out, job.task, job.stream, size, job.seed))
    return job


def dataset_jobs(out: Path, scene: str, tasks: Sequence[str], training_seeds: Sequence[int],
                 sizes: Sequence[int], test_seed: int, test_scenes: int) -> list[DatasetJob]:
    """The collections still to do: training sets per task and seed, a test set per task."""
    from sim.scene import SeedStream

    wanted = [(task, seed, SeedStream.TRAIN, tuple(sizes)) for task in tasks
              for seed in training_seeds]
    wanted += [(task, test_seed, SeedStream.TEST, (test_scenes,)) for task in tasks]
    jobs = []
    for task, seed, stream, sizes in wanted:
        missing = tuple(sorted(s for s in sizes if not dataset_present(
            dataset_path(out, task, stream, s, seed), scene, task, s, seed, stream)))
        if missing:
            jobs.append(DatasetJob(task, seed, stream, missing, out, scene))
    return jobs
