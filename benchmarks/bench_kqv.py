"""The KQV model's CPU budget and accuracy: inference latency, training time, test errors.

    python benchmarks/bench_kqv.py [--pair TRAIN.gva TEST.gva]... [--repeats 200]
        [--steps 1000] [--out benchmarks/results/kqv.json]

Without ``--pair`` it collects the issue's two pairs itself (paper-sim ``single`` and
``selected-type``: 20 training scenes of seed 0, 100 test scenes of seed 1000) into a
temporary folder.

Inference: median wall time of ``predict(image, condition)`` at batch 1 on a 128 x 128 image
(bar: 5 ms), for position and grasp labels. For each ``--pair`` of datasets (from ``gva
collect``; the test set from another seed, so no test scene was trained on): the training time
(bar: 180 s for 20 scenes on 2 cores), the mean position error on the test scenes (bars: 2 cm
for ``single``, 3 cm for ``selected-type``) and, for a conditioned task, how often switching the
condition puts the attention point on the object the condition names (bar: 95 % of scenes;
``perception.learning.evaluate.attention_on_named``, on a test set collected with
``--every-condition``).
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import tempfile
import time
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np
import torch
from results_file import add_out_option, write_record

from perception.interface import ConditionKind, LabelKind
from perception.learning.dataset_file import load_dataset
from perception.learning.evaluate import evaluate
from perception.learning.learnable import ModelSpec
from perception.learning.torch_pieces import LabelScaler
from perception.learning.train import TrainConfig, available_threads
from perception.models.kqv import KqvConfig, KqvModel

ERROR_BARS_CM = {"single": 2.0, "selected-type": 3.0}
INFERENCE_BAR_MS, TRAINING_BAR_S, SWITCH_BAR = 5.0, 180.0, 0.95


def inference_ms(kind: LabelKind, repeats: int, threads: int) -> float:
    """Median ``predict`` wall time [ms] of an untrained q = 1 model on 128 x 128 images."""
    spec = ModelSpec("bench", "single", kind, 1, ConditionKind.NONE, (), 128, 128)
    model = KqvModel(spec, KqvConfig(), LabelScaler((0.45, 0.0, 0.05), 0.2))
    image = np.random.default_rng(0).integers(0, 256, (128, 128, 3), dtype=np.uint8)
    torch.set_num_threads(threads)
    for _ in range(20):  # warm-up: allocator, oneDNN kernels
        model.predict(image)
    times = []
    for _ in range(repeats):
        started = time.perf_counter()
        model.predict(image)
        times.append(time.perf_counter() - started)
    return statistics.median(times) * 1e3


def accuracy(train_path: Path, test_path: Path, steps: int) -> dict[str, Any]:
    """Trains on one dataset with the default settings (``steps`` steps) and scores on another."""
    train_set, test_set = load_dataset(train_path), load_dataset(test_path)
    model = KqvModel.for_dataset(train_set)
    started = time.perf_counter()
    report = model.fit(train_set, TrainConfig(steps=steps), progress=False)
    training_s = time.perf_counter() - started
    result = evaluate(model, test_set)
    task = train_set.metadata.task
    row: dict[str, Any] = {
        "scene": train_set.metadata.scene, "task": task, "train": str(train_path),
        "train_size": len(train_set), "train_seed": train_set.metadata.seed,
        "test": str(test_path), "test_size": len(test_set), "test_seed": test_set.metadata.seed,
        "steps": steps, "training_s": round(training_s, 1), "training_bar_s": TRAINING_BAR_S,
        "threads": report.threads, "final_loss": report.final_loss,
        "mean_position_error_cm": round(result.mean_position_error_cm, 3),
        "median_position_error_cm": round(result.median_position_error_cm, 3),
        "error_bar_cm": ERROR_BARS_CM.get(task),
        "mean_angle_error_deg": result.mean_angle_error_deg,
    }
    print(f"{result.headline()}; trained in {training_s:.1f} s ({steps} steps, "
          f"{report.threads} threads)")
    if result.attention_switch_fraction is not None:  # a test set asked every condition
        row["attention_switch_rate"] = result.attention_switch_fraction
        row["switch_bar"] = SWITCH_BAR
        print(f"switching the condition moves attention onto the named object in "
              f"{row['attention_switch_rate']:.0%} of test scenes")
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pair", nargs=2, type=Path, action="append", default=[],
                        metavar=("TRAIN", "TEST"), help="training and test datasets")
    parser.add_argument("--steps", type=int, default=TrainConfig().steps)
    parser.add_argument("--repeats", type=int, default=200)
    add_out_option(parser, "kqv")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        run(args, args.pair or default_pairs(Path(folder)))


def default_pairs(folder: Path) -> list[tuple[Path, Path]]:
    """Collects paper-sim single and selected-type: 20 scenes of seed 0, 100 of seed 1000.

    Each scene of a conditioned task is asked every condition (the test scenes too), so the
    evaluation can say whether switching the condition moves the attention.
    """
    from harness.inputs.collector import CollectSettings, collect

    pairs = []
    for task in ERROR_BARS_CM:
        paths = []
        for size, seed in ((20, 0), (100, 1000)):
            path = folder / f"paper-sim-{task}-{size}-s{seed}.gva"
            collect(CollectSettings(scene="paper-sim", task=task, size=size, seed=seed,
                                    every_condition=True), path, progress=False)
            paths.append(path)
        pairs.append((paths[0], paths[1]))
    return pairs


def run(args: argparse.Namespace, pairs: list[tuple[Path, Path]]) -> None:
    """Measures inference, then trains and scores on each pair; writes ``args.out``."""
    threads = available_threads()
    inference = {}
    for kind in LabelKind:
        for count in sorted({1, threads}):
            median = inference_ms(kind, args.repeats, count)
            inference[f"{kind.value}_{count}_threads_ms"] = round(median, 3)
            print(f"inference, {kind.value} labels, batch 1, {count} thread(s): median "
                  f"{median:.2f} ms (bar {INFERENCE_BAR_MS} ms)")
    result: dict[str, Any] = {
        "benchmark": "kqv", "config": asdict(KqvConfig()), "train_config": asdict(TrainConfig()),
        "machine": {"cpus": os.cpu_count(), "threads": threads, "torch": torch.__version__,
                    "python": platform.python_version(), "platform": platform.platform(),
                    "load_average_1min": os.getloadavg()[0]},
        "inference": inference | {"bar_ms": INFERENCE_BAR_MS, "repeats": args.repeats},
    }
    result["accuracy"] = [accuracy(train, test, args.steps) for train, test in pairs]
    write_record(args.out, result, default=str)


if __name__ == "__main__":
    main()
