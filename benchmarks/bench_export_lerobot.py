"""Wall time and size of ``gva export --format lerobot`` and ``gva import``, median of repeats.

    python benchmarks/bench_export_lerobot.py [--data runs/yumi-multiple-20.gva] [--repeats 3]
        [--out benchmarks/results/export_lerobot.json]

The dataset: 20 ``multiple`` demonstrations on the yumi scene (60 samples, 128 x 128), collected
once into ``runs/`` when missing (a minute or two). Each export writes a fresh folder in a
temporary folder; each import reads the first one back and must equal the file, byte for byte.
The bar: export and import each within 10 s on a 2-core machine.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import tempfile
import time
from pathlib import Path

from results_file import add_out_option, write_record

from perception.learning.dataset_file import load_dataset, save_dataset
from perception.learning.lerobot_format import export_lerobot, import_lerobot

BAR_S = 10.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path("runs/yumi-multiple-20.gva"))
    parser.add_argument("--repeats", type=int, default=3)
    add_out_option(parser, "export_lerobot")
    args = parser.parse_args()
    if not args.data.exists():
        from harness.inputs.collector import CollectSettings, collect  # pybullet: only when missing

        print(f"collecting {args.data} (20 yumi demonstrations of multiple, seed 0)")
        collect(CollectSettings("yumi", "multiple", 20, seed=0), args.data)
    dataset = load_dataset(args.data)
    load_before = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as folder:
        exports = [export_lerobot(dataset, Path(folder) / f"export-{n}")
                   for n in range(args.repeats)]
        import_s, same = [], True
        for _ in range(args.repeats):
            started = time.perf_counter()
            back = import_lerobot(exports[0].folder)
            import_s.append(time.perf_counter() - started)
            same = same and back == dataset
        file_bytes = save_dataset(back, Path(folder) / "back.gva").read_bytes()
        same = same and file_bytes == args.data.read_bytes()
        parts = {str(p.relative_to(exports[0].folder)): p.stat().st_size
                 for p in sorted(exports[0].folder.rglob("*")) if p.is_file()}
    export_s = [e.seconds for e in exports]
    result = {
        "machine": {"cpu_count": os.cpu_count(), "python": platform.python_version(),
                    "load_average_1min_before": round(load_before, 2),
                    "load_average_1min_after": round(os.getloadavg()[0], 2)},
        "dataset": {"path": str(args.data), "scene": dataset.metadata.scene,
                    "task": dataset.metadata.task, "samples": len(dataset),
                    "file_mb": round(args.data.stat().st_size / 1e6, 3)},
        "repeats": args.repeats, "episodes": exports[0].episodes, "frames": exports[0].frames,
        "export_median_s": round(statistics.median(export_s), 3),
        "export_runs_s": [round(t, 3) for t in export_s],
        "import_median_s": round(statistics.median(import_s), 3),
        "import_runs_s": [round(t, 3) for t in import_s],
        "folder_mb": round(exports[0].bytes_written / 1e6, 3),
        "files_bytes": parts, "bar_s": BAR_S,
        "within_bar": max(statistics.median(export_s), statistics.median(import_s)) <= BAR_S,
        "round_trip_identical": same,
    }
    print(f"{len(dataset)} samples, {exports[0].episodes} episodes: export median "
          f"{result['export_median_s']} s, import median {result['import_median_s']} s, folder "
          f"{result['folder_mb']} MB (the .gva: {result['dataset']['file_mb']} MB); round trip "
          f"{'identical' if same else 'DIFFERS'}; load {load_before:.2f} before")
    write_record(args.out, result)


if __name__ == "__main__":
    main()
