"""What is bit-for-bit: the same training, repeated, with one and two threads, on this CPU.

    python benchmarks/bench_determinism.py [--steps 40] [--out benchmarks/results/determinism.json]
    ATEN_CPU_CAPABILITY=avx2 ONEDNN_MAX_CPU_ISA=AVX2 python benchmarks/bench_determinism.py

Collects a paper-sim ``single`` dataset of 4 scenes (twice, comparing the files' hashes),
trains ``kqv`` on it from seed 0, twice per thread count, and hashes the weights. The record
keeps one entry per instruction set of torch's CPU kernels (the second command above makes a
machine's torch use AVX2 kernels, as a CPU without AVX-512 would), so that one file compares
two kernel sets measured on one machine: what docs/reproducing.md#what-is-bit-for-bit says
is read off it.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import tempfile
from pathlib import Path
from typing import Any

import torch
from results_file import add_out_option, write_record

from harness.inputs.collector import CollectSettings, collect
from harness.provenance import provenance
from perception.files import file_sha256
from perception.learning.dataset_file import load_dataset
from perception.learning.train import TrainConfig
from perception.models.kqv import KqvConfig, KqvModel


def weights_sha256(model: KqvModel) -> str:
    """The hash of every parameter's bytes, in the network's order."""
    digest = hashlib.sha256()
    for tensor in model.network.state_dict().values():
        digest.update(tensor.detach().contiguous().numpy().tobytes())
    return digest.hexdigest()


def measure(steps: int, folder: Path) -> dict[str, Any]:
    """Two collections of one dataset and two trainings per thread count, hashed."""
    paths = [folder / f"single-{i}.gva" for i in range(2)]
    for path in paths:
        collect(CollectSettings(scene="paper-sim", task="single", size=4, seed=0), path,
                progress=False)
    dataset = load_dataset(paths[0])
    trainings = []
    for threads in (1, 2, 1, 2):
        model = KqvModel.for_dataset(dataset, KqvConfig(seed=0))
        report = model.fit(dataset, TrainConfig(steps=steps, threads=threads), progress=False)
        trainings.append({"threads": report.threads, "final_loss": report.final_loss,
                          "weights_sha256": weights_sha256(model)})
        print(f"{report.threads} thread(s): final loss {report.final_loss:.6f}, "
              f"weights {trainings[-1]['weights_sha256'][:16]}")
    by_threads: dict[int, set[str]] = {}
    for row in trainings:
        by_threads.setdefault(row["threads"], set()).add(row["weights_sha256"])
    return {
        "dataset_sha256": [file_sha256(path) for path in paths],
        "dataset_identical": file_sha256(paths[0]) == file_sha256(paths[1]),
        "steps": steps,
        "trainings": trainings,
        "same_threads_identical": all(len(hashes) == 1 for hashes in by_threads.values()),
        "one_and_two_threads_identical": len(set().union(*by_threads.values())) == 1,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=40)
    add_out_option(parser, "determinism")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        row = measure(args.steps, Path(folder))
    capability = str(torch.backends.cpu.get_cpu_capability())
    row["provenance"] = provenance()
    record = json.loads(args.out.read_text()) if args.out.exists() else {
        "benchmark": "determinism", "by_cpu_capability": {}}
    record["by_cpu_capability"][capability] = row
    kernels = record["by_cpu_capability"]
    record["weights_identical_across_capabilities"] = (
        None if len(kernels) < 2 else
        len({r["trainings"][0]["weights_sha256"] for r in kernels.values()}) == 1)
    write_record(args.out, record, announce=False)
    print(f"{capability}: dataset identical {row['dataset_identical']}, same threads identical "
          f"{row['same_threads_identical']}, 1 vs 2 threads identical "
          f"{row['one_and_two_threads_identical']}; across kernel sets identical "
          f"{record['weights_identical_across_capabilities']}; wrote {args.out}")


if __name__ == "__main__":
    main()
