"""Benchmark: what a served model costs per pick over loopback, against the model in-process.

``gva serve MODEL`` runs in its own process (one torch thread, as it always does); this process
renders ``--frames`` head-camera frames of ``--task``'s test scenes (seed ``--seed``, through the
task's sensor, else the checkpoint's, as ``gva trials`` does) and then makes ``--n`` predictions,
cycling over those frames: each through the remote model (``--model ws://``: encode, send, the
server's decode, predict and encode, receive, decode) and, paired with it, through the same
model loaded here on one thread. The record gives each path's median and 95th percentile [ms],
the per-pick overhead (remote minus in-process, pair by pair), whether the two predicted the
same, and the bytes a pick sends and receives: the msgpack payloads and, with their websocket
frame headers (a client's frames are masked: 4 bytes more), what goes on the wire above TCP.

Usage:
    python benchmarks/bench_serve.py --model CHECKPOINT [--task single] [--n 100] [--frames 10]
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import platform
import statistics
import subprocess
import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
from results_file import add_out_option, write_record
from websockets.sync.client import connect

from harness.inputs.trial_settings import TrialSettings
from perception.camera import RgbdFrame
from perception.interface import Condition, PerceptionModel, Prediction
from perception.remote.client import RemoteModel
from perception.remote.codec import pack
from perception.remote.messages import request_message
from perception.remote.server import MAX_MESSAGE_BYTES, load_served_model
from sim.trials.trial_models import torch_threads
from sim.trials.trial_runner import TrialRunner
from sim.trials.trial_scenes import trial_scene

ROOT = Path(__file__).resolve().parents[1]


@dataclass(frozen=True)
class Timing:
    """Wall times of one path over the predictions [ms]."""

    median_ms: float
    p95_ms: float
    mean_ms: float

    @classmethod
    def of(cls, times_ms: list[float]) -> Timing:
        """The timing of ``times_ms``."""
        return cls(round(statistics.median(times_ms), 3),
                   round(float(np.percentile(times_ms, 95)), 3),
                   round(statistics.fmean(times_ms), 3))


@dataclass(frozen=True)
class Bytes:
    """What one pick moves over the connection, per frame of ``--frames`` (medians)."""

    request_payload: int
    reply_payload: int
    sent_on_wire: int
    received_on_wire: int


def frame_header_bytes(payload: int, masked: bool) -> int:
    """The websocket frame header for ``payload`` bytes (RFC 6455 5.2); a client's is masked."""
    length = 2 if payload < 126 else 4 if payload < 2**16 else 10
    return length + 4 * masked


def add_served_options(parser: argparse.ArgumentParser) -> None:
    """The options both serve benchmarks take (this one and ``bench_serve_clients.py``).

    The model served, the task and seed of the frames it predicts, how many, and a note on how
    busy the machine was.
    """
    parser.add_argument("--model", required=True, help="a checkpoint folder (or a plug-in)")
    parser.add_argument("--task", default="single")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--frames", type=int, default=10, help="distinct frames cycled over")
    parser.add_argument("--note", default="", help="how busy the machine was, in words")


def frames_of(settings: TrialSettings, model: PerceptionModel, count: int
              ) -> list[tuple[RgbdFrame, Condition]]:
    """The head camera's frames of the first ``count`` test scenes, with their conditions."""
    task = settings.task_spec
    seen = []
    with TrialRunner(task, lambda world, camera: model, robot=settings.description()) as runner:
        for index in range(count):
            scene = trial_scene(task, settings.seed, index)
            runner.setup(scene)
            seen.append((runner.sense(), scene.given))
    return seen


def serve(model: str) -> tuple[subprocess.Popen[str], str]:
    """``gva serve model`` on a free port, in its own process; the process and its address."""
    env = os.environ | {"PYTHONPATH": os.pathsep.join(
        [str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])])}
    process = subprocess.Popen([sys.executable, "-m", "experiments.cli", "serve", model,
                                "--port", "0"], env=env, stdout=subprocess.PIPE,
                               stderr=subprocess.DEVNULL, text=True)
    assert process.stdout is not None
    line = process.stdout.readline()
    if " on ws://" not in line:
        process.kill()
        raise SystemExit(f"gva serve {model} did not start: {line!r}")
    return process, "ws://" + line.rsplit("ws://", 1)[1].strip()


def same(a: Prediction, b: Prediction) -> bool:
    """Whether two predictions name the same targets, bit for bit."""
    return len(a.targets) == len(b.targets) and all(
        _equal(x.position_m, y.position_m) and _equal(x.rotation, y.rotation)
        and x.object_type == y.object_type for x, y in zip(a.targets, b.targets, strict=True))


def _equal(a: np.ndarray | None, b: np.ndarray | None) -> bool:
    return (a is None and b is None) or (a is not None and b is not None and
                                         bool(np.array_equal(a, b)))


def wire_bytes(url: str, frames: list[tuple[RgbdFrame, Condition]]) -> Bytes:
    """The payload of each frame's request and reply, read off a plain connection."""
    requests, replies = [], []
    with connect(url, compression=None, max_size=MAX_MESSAGE_BYTES) as connection:
        connection.recv()  # the metadata
        for frame, condition in frames:
            data = pack(request_message(frame, condition))
            connection.send(data)
            reply = connection.recv()
            requests.append(len(data))
            replies.append(len(reply))
    sent, received = int(statistics.median(requests)), int(statistics.median(replies))
    return Bytes(sent, received, sent + frame_header_bytes(sent, masked=True),
                 received + frame_header_bytes(received, masked=False))


def timed(model: PerceptionModel, frame: RgbdFrame, condition: Condition
          ) -> tuple[float, Prediction]:
    """The wall time of ``model``'s prediction for ``frame`` [ms], and the prediction."""
    started = time.perf_counter()
    prediction = model.predict_frame(frame, condition)
    return (time.perf_counter() - started) * 1e3, prediction


def main(argv: list[str] | None = None) -> int:
    """Measures, writes ``--out`` and prints the numbers; the exit status."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_served_options(parser)
    parser.add_argument("--n", type=int, default=100, help="predictions per path")
    parser.add_argument("--warmup", type=int, default=5)
    add_out_option(parser, "serve_overhead")
    args = parser.parse_args(argv)
    load_before = os.getloadavg()
    settings = TrialSettings(args.model, args.task, seed=args.seed)
    here = load_served_model(args.model)
    frames = frames_of(settings, here, args.frames)
    process, url = serve(args.model)
    try:
        remote = RemoteModel(url)
        local_ms: list[float] = []
        remote_ms: list[float] = []
        identical = 0
        with torch_threads(1) if "torch" in sys.modules else contextlib.nullcontext():
            for k in range(args.warmup + args.n):
                frame, condition = frames[k % len(frames)]
                t_here, a = timed(here, frame, condition)
                t_there, b = timed(remote, frame, condition)
                if k >= args.warmup:
                    local_ms.append(t_here)
                    remote_ms.append(t_there)
                    identical += same(a, b)
        remote.close()
        sizes = wire_bytes(url, frames)
    finally:
        process.kill()
        process.wait(timeout=30)
    overhead = [r - h for r, h in zip(remote_ms, local_ms, strict=True)]
    record = {
        "what": "per-pick overhead of a gva serve model over loopback (its own process) against "
                "the same model in-process, paired predictions of the same frames",
        "command": "python benchmarks/bench_serve.py " + " ".join(
            sys.argv[1:] if argv is None else argv),
        "model": str(args.model), "task": args.task, "seed": args.seed, "n": args.n,
        "frames": args.frames, "warmup": args.warmup,
        "announced": {k: v for k, v in remote.announced.items() if k != "spec"},
        "in_process": asdict(Timing.of(local_ms)), "remote": asdict(Timing.of(remote_ms)),
        "overhead": asdict(Timing.of(overhead)),
        "identical_predictions": f"{identical}/{args.n}",
        "bytes_per_pick": asdict(sizes),
        "machine": {"cpus": os.cpu_count(), "python": platform.python_version(),
                    "platform": platform.platform(),
                    "load_average_1_5_15min_before": [round(v, 2) for v in load_before],
                    "load_average_1_5_15min_after": [round(v, 2) for v in os.getloadavg()],
                    "note": "client and server share the machine's cores (loopback)"
                    + (f"; {args.note}" if args.note else "")},
    }
    write_record(args.out, record, announce=False)
    print(json.dumps({k: record[k] for k in ("in_process", "remote", "overhead",
                                             "identical_predictions", "bytes_per_pick")},
                     indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
