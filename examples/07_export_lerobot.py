"""A gva dataset as a LeRobotDataset v3.0 folder, and back: the same bytes.

    python examples/07_export_lerobot.py

Collects a tiny dataset (4 paper-sim scenes of `selected-type`, one sample per condition value:
12 samples, under a second), exports it to runs/lerobot-example/ (as `gva export --format
lerobot` does), reads the folder's parts as LeRobot would, imports it back (as `gva import`
does) and checks the dataset file it gives is the one collected, byte for byte. Needs pyarrow
(`pip install 'gva[lerobot]'`); docs/lerobot.md says what maps to what.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pyarrow.parquet as pq

from harness.inputs.collector import CollectSettings, collect
from perception.learning.dataset_file import save_dataset
from perception.learning.lerobot_format import export_lerobot, import_lerobot

OUT = Path("runs/lerobot-example")


def main() -> None:
    shutil.rmtree(OUT, ignore_errors=True)  # the example's own folder: a fresh run each time
    dataset = collect(CollectSettings("paper-sim", "selected-type", size=4, seed=0),
                      OUT / "demos.gva", progress=False)
    result = export_lerobot(OUT / "demos.gva", OUT / "lerobot")
    print(f"{result.frames} samples -> {result.episodes} episodes, "
          f"{result.bytes_written / 1e3:.0f} kB in {result.seconds:.2f} s: {result.folder}")

    info = json.loads((result.folder / "meta/info.json").read_text())
    print(f"codebase_version {info['codebase_version']}, fps {info['fps']}, features:")
    for name, feature in info["features"].items():
        print(f"  {name:<26} {feature['dtype']:<8} {feature['shape']}")
    frames = pq.read_table(result.folder / "data/chunk-000/file-000.parquet")
    tasks = pq.read_table(result.folder / "meta/tasks.parquet").column("task").to_pylist()
    first = frames.slice(0, 1).to_pylist()[0]
    print(f"frame 0: episode {first['episode_index']}, task {tasks[first['task_index']]!r}, "
          f"condition {first['observation.condition']}, "
          f"PNG of {len(first['observation.images.head']['bytes'])} bytes")

    back = import_lerobot(result.folder)
    again = save_dataset(back, OUT / "again.gva")
    same = again.read_bytes() == (OUT / "demos.gva").read_bytes()
    print(f"imported {len(back)} samples; the same file as collected: {same}")
    assert same and back == dataset


if __name__ == "__main__":
    main()
