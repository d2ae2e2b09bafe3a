"""Where a kqv training's time goes, on one CPU thread, as the seed sweeps train it.

    python benchmarks/bench_train.py [--steps 40] [--repeats 5]
        [--out benchmarks/results/train.json]

A seed sweep (``gva reproduce sim``, ``gva reproduce real --seeds``) is dominated by training:
each cell trains one kqv on one thread, two cells side by side on this 2-core machine. This
times, on a ``yumi`` ``multiple`` batch (6 demonstrations, 18 images: a full batch of 16; a 64
x 64 heatmap, the heaviest yumi task) and a ``paper-sim`` ``single`` batch (20 scenes, a 32 x 32
heatmap):

- a whole pose step (forward, loss, backward, Adam) and its parts: the photometric
  augmentation, the forward pass, the backward pass;
- the Key normalisation of the cosine similarity, as ``F.normalize`` against the reciprocal
  square root kqv uses (:func:`perception.learning.torch_pieces.unit`), forward and backward;
- the whole step again with the Key network's coordinates concatenated to every map between
  its layers (its :class:`~perception.learning.torch_pieces.CoordConv` layers run one by one,
  as before :class:`~perception.learning.torch_pieces.CoordConvStack`): the same function,
  its peer in the same run;
- a step of the type head's phase (forward through the frozen network, the small head's
  backward);
- the work of a pose step (``torch.utils.flop_counter``: forward and backward), the rate it
  reaches, and that rate against a 1024 x 1024 float32 matmul's on the same thread (the
  core's practical peak): how far a faster step could come from faster kernels, and how far
  it must come from doing less work.

Medians of ``--repeats`` runs of ``--steps`` steps each, after a warm-up; the training's step
count (:class:`~perception.learning.train.TrainConfig`, :class:`~perception.models.kqv.KqvConfig`'s
starts) turns them into a training's seconds.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import torch
from results_file import add_out_option, write_record
from torch.utils.flop_counter import FlopCounterMode

from perception.learning.data import Dataset
from perception.learning.torch_pieces import images_to_tensor, unit
from perception.learning.train import Batch, TrainConfig, batch_indices, photometric_augment
from perception.models.kqv import KqvModel
from perception.models.kqv_net import KqvNet
from perception.registry import new_model


def median_ms(run: Callable[[], Any], steps: int, repeats: int) -> float:
    """Median over ``repeats`` of the mean wall time of ``steps`` calls of ``run`` [ms]."""
    for _ in range(3):
        run()
    times = []
    for _ in range(repeats):
        started = time.perf_counter()
        for _ in range(steps):
            run()
        times.append((time.perf_counter() - started) / steps)
    return statistics.median(times) * 1e3


def matmul_gflop_per_s(size: int = 1024, repeats: int = 20) -> float:
    """A ``size`` x ``size`` float32 matmul's rate on this thread [GFLOP/s], median."""
    a, b = torch.randn(size, size), torch.randn(size, size)
    return 2 * size**3 / (median_ms(lambda: a @ b, 5, repeats) * 1e-3) / 1e9


def concatenated(network: KqvNet, run: Callable[[], None], steps: int,
                 repeats: int) -> float:
    """:func:`median_ms` of ``run`` with the Key network's layers run one by one.

    Each :class:`CoordConv` layer then appends its coordinates to every map and the next
    convolves them with the features: what :class:`CoordConvStack` replaced.
    """
    stack = network.key_net
    network.key_net = torch.nn.Sequential(*stack.children())  # type: ignore[assignment]
    try:
        return median_ms(run, steps, repeats)
    finally:
        network.key_net = stack


def step_parts(dataset: Dataset, steps: int, repeats: int) -> dict[str, float]:
    """Milliseconds of a pose step and its parts, and of a type-phase step, on one thread."""
    model = new_model("kqv", dataset, seed=0)
    assert isinstance(model, KqvModel)
    model.fit(dataset, TrainConfig(steps=1, threads=1), progress=False)  # scaler, mirror
    network = model.network.train()
    optimiser = torch.optim.Adam(network.parameters(), lr=1e-4)
    rng, generator = np.random.default_rng(0), torch.Generator().manual_seed(0)
    index = next(batch_indices(len(dataset), 16, rng))
    raw = images_to_tensor(dataset.images[index])
    images = photometric_augment(raw, generator)
    batch = Batch(images, torch.from_numpy(dataset.conditions[index]),
                  torch.from_numpy(dataset.labels[index]),
                  torch.from_numpy(dataset.target_type_indices()[index]),
                  torch.from_numpy(dataset.target_present()[index]),
                  None if dataset.depths_m is None else torch.from_numpy(dataset.depths_m[index]))

    def whole() -> None:
        loss = model.batch_loss(batch._replace(images=photometric_augment(raw, generator)))
        optimiser.zero_grad()
        loss.backward()
        optimiser.step()

    def forward() -> torch.Tensor:
        return model.batch_loss(batch)

    def backward() -> None:
        optimiser.zero_grad()
        forward().backward()

    with torch.no_grad():
        heatmap = network.attend(raw[:1], network.queries(batch.conditions[:1])).heatmaps
    keys = torch.randn(16, model.config.key_dim + 2, *heatmap.shape[-2:], requires_grad=True)

    def normalise(function: Callable[[torch.Tensor], torch.Tensor]) -> Callable[[], None]:
        def run() -> None:
            function(keys).sum().backward()
        return run

    result = {"step_ms": median_ms(whole, steps, repeats),
              "step_coordinates_concatenated_ms": concatenated(network, whole, steps, repeats),
              "augment_ms": median_ms(lambda: photometric_augment(raw, generator), steps,
                                      repeats),
              "forward_ms": median_ms(forward, steps, repeats)}
    result["backward_ms"] = median_ms(backward, steps, repeats) - result["forward_ms"]
    with FlopCounterMode(display=False) as counter:
        whole()
    result["step_gflop"] = counter.get_total_flops() / 1e9
    result["step_gflop_per_s"] = result["step_gflop"] / (result["step_ms"] * 1e-3)
    result["normalise_f_normalize_ms"] = median_ms(normalise(
        lambda k: torch.nn.functional.normalize(k, dim=1)), steps, repeats)
    result["normalise_rsqrt_ms"] = median_ms(normalise(lambda k: unit(k, dim=1)), steps,
                                             repeats)
    if network.type_head is not None:
        head_optimiser = torch.optim.Adam(network.type_head.parameters(), lr=1e-3)

        def type_step() -> None:
            loss = model.type_loss(batch)
            head_optimiser.zero_grad()
            loss.backward()
            head_optimiser.step()

        result["type_step_ms"] = median_ms(type_step, steps, repeats)
        with FlopCounterMode(display=False) as counter:
            type_step()
        result["type_step_gflop"] = counter.get_total_flops() / 1e9
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=40)
    parser.add_argument("--repeats", type=int, default=5)
    add_out_option(parser, "train")
    args = parser.parse_args()
    from harness.inputs.collector import CollectSettings, collect

    torch.set_num_threads(1)
    rows = {}
    with tempfile.TemporaryDirectory() as folder:
        for scene, task, size in (("yumi", "multiple", 6), ("yumi", "single", 16),
                                  ("paper-sim", "single", 20)):
            dataset = collect(CollectSettings(scene, task, size, seed=0),
                              Path(folder) / f"{scene}-{task}.gva", progress=False)
            rows[f"{scene}/{task}"] = step_parts(dataset, args.steps, args.repeats)
            print(scene, task, {k: round(v, 1) for k, v in rows[f"{scene}/{task}"].items()},
                  flush=True)
    matmul = matmul_gflop_per_s()
    for row in rows.values():
        row["fraction_of_matmul_rate"] = row["step_gflop_per_s"] / matmul
    print(f"1024 x 1024 float32 matmul: {matmul:.1f} GFLOP/s on one thread; a step reaches "
          + ", ".join(f"{name} {row['fraction_of_matmul_rate']:.0%}"
                      for name, row in rows.items()))
    data = {"benchmark": "train", "threads": 1, "batch_size": 16, "steps": args.steps,
            "repeats": args.repeats, "matmul_1024_gflop_per_s": matmul, "rows": rows,
            "machine": {"cpus": os.cpu_count(), "python": platform.python_version(),
                        "torch": torch.__version__, "platform": platform.platform(),
                        "load_average_1min": os.getloadavg()[0]}}
    write_record(args.out, data)


if __name__ == "__main__":
    main()
