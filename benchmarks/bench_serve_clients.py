"""Benchmark: whether ``gva serve`` keeps answering every one of many concurrent clients.

Issue 77's bar: ``gva serve`` under 20 concurrent clients keeps answering all of them. The
server runs predictions one at a time (a torch model is not thread-safe), so many clients queue:
what matters is that none is dropped, refused or starved, and how long a request then waits.
``gva serve MODEL`` runs in its own process (as ``bench_serve.py`` starts it); this process
renders ``--frames`` head-camera frames of ``--task``'s test scenes (seed ``--seed``), then, all
at once: ``--clients`` threads, each its own :class:`RemoteModel` (its own websocket), each
sending ``--requests`` predictions of those frames one after another; beside them one idle
client (a websocket that reads the metadata and sends nothing) and one silent TCP socket (that
connects and never says a word, not even the handshake). Each request's latency is the wall
time of ``predict_frame`` (a client's first includes its connect and the metadata); it is
answered when a prediction came back, else failed, with the reason. The record gives the
answered and failed counts (failures by reason), latency median, 95th percentile and maximum
over the answered requests [s], the wall time of the whole load, and the machine's load. The
exit status is 1 if any request went unanswered.

Usage:
    python benchmarks/bench_serve_clients.py --model CHECKPOINT [--task single] [--clients 20]
        [--requests 20] [--frames 10] [--timeout 60] [--note WORDS]
"""

from __future__ import annotations

import argparse
import collections
import os
import platform
import shlex
import socket
import statistics
import sys
import threading
import time
from dataclasses import asdict, dataclass
from typing import Any
from urllib.parse import urlsplit

import numpy as np
from bench_serve import add_served_options, frames_of, serve
from results_file import add_out_option, write_record
from websockets.sync.client import connect

from harness.inputs.trial_settings import TrialSettings
from perception.camera import RgbdFrame
from perception.interface import Condition, Prediction
from perception.remote.client import RemoteModel, announced_metadata
from perception.remote.server import MAX_MESSAGE_BYTES, load_served_model


@dataclass(frozen=True)
class Outcome:
    """One request: which client sent it, its latency [s], and why it failed (None: answered)."""

    client: int
    index: int
    latency_s: float
    failure: str | None


@dataclass(frozen=True)
class Latency:
    """Latencies of the answered requests [s]."""

    median_s: float
    p95_s: float
    max_s: float

    @classmethod
    def of(cls, times_s: list[float]) -> Latency | None:
        """The latency of ``times_s``; None if there is none."""
        if not times_s:
            return None
        return cls(round(statistics.median(times_s), 4),
                   round(float(np.percentile(times_s, 95)), 4), round(max(times_s), 4))


@dataclass(frozen=True)
class Failures:
    """Requests that failed for one reason."""

    reason: str
    count: int


@dataclass(frozen=True)
class Machine:
    """Where it ran and how busy the machine was (load averages over 1, 5 and 15 min)."""

    cpus: int | None
    python: str
    platform: str
    load_average_before: tuple[float, float, float]
    load_average_after: tuple[float, float, float]
    note: str


@dataclass(frozen=True)
class Record:
    """What ``benchmarks/results/serve_clients.json`` holds."""

    what: str
    command: str
    model: str
    task: str
    seed: int
    clients: int
    requests_per_client: int
    frames: int
    idle_client: bool
    silent_socket: bool
    answered: int
    failed: int
    failures: tuple[Failures, ...]
    latency: Latency | None
    wall_s: float
    idle_client_open_at_end: bool
    machine: Machine


def client(url: str, announced: dict[str, Any], timeout_s: float, number: int, requests: int,
           frames: list[tuple[RgbdFrame, Condition]], start: threading.Barrier,
           outcomes: list[Outcome]) -> None:
    """One client's ``requests`` predictions over its own connection, each appended."""
    start.wait()
    model = RemoteModel(url, timeout_s, announced=announced)  # connects at its first request
    try:
        for k in range(requests):
            frame, condition = frames[(number + k) % len(frames)]
            began = time.perf_counter()
            try:
                prediction = model.predict_frame(frame, condition)
                failure = (None if isinstance(prediction, Prediction)
                           else f"not a prediction: {type(prediction).__name__}")
            except Exception as error:  # a failure is this benchmark's answer, not a crash
                failure = f"{type(error).__name__}: {error}"
            outcomes.append(Outcome(number, k, time.perf_counter() - began, failure))
    finally:
        model.close()


def load_average() -> tuple[float, float, float]:
    """The machine's load averages over 1, 5 and 15 minutes, rounded."""
    one, five, fifteen = os.getloadavg()
    return round(one, 2), round(five, 2), round(fifteen, 2)


def run_load(url: str, args: argparse.Namespace, frames: list[tuple[RgbdFrame, Condition]]
             ) -> tuple[list[Outcome], float, bool]:
    """The clients, the idle client and the silent socket at once; the outcomes and wall [s].

    Also whether the idle client's connection was still open once every client had finished.
    """
    announced = dict(announced_metadata(url, args.timeout))
    parts = urlsplit(url)
    outcomes: list[Outcome] = []
    start = threading.Barrier(args.clients + 1)
    threads = [threading.Thread(target=client, args=(url, announced, args.timeout, n,
                                                     args.requests, frames, start, outcomes))
               for n in range(args.clients)]
    with socket.create_connection((parts.hostname, parts.port), timeout=args.timeout), \
            connect(url, compression=None, max_size=MAX_MESSAGE_BYTES) as idle:
        idle.recv(timeout=args.timeout)  # the metadata; then it says nothing
        for thread in threads:
            thread.start()
        start.wait()
        began = time.perf_counter()
        for thread in threads:
            thread.join()
        wall = time.perf_counter() - began
        idle_open = idle.state.name == "OPEN"
    return outcomes, wall, idle_open


def main(argv: list[str] | None = None) -> int:
    """Measures, writes ``--out`` and prints one line; 1 if any request went unanswered."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_served_options(parser)
    parser.add_argument("--clients", type=int, default=20, help="concurrent clients")
    parser.add_argument("--requests", type=int, default=20, help="predictions per client")
    parser.add_argument("--timeout", type=float, default=60.0,
                        help="a client's limit per connect and per prediction [s]")
    add_out_option(parser, "serve_clients")
    args = parser.parse_args(argv)
    load_before = load_average()
    settings = TrialSettings(args.model, args.task, seed=args.seed)
    frames = frames_of(settings, load_served_model(args.model), args.frames)
    process, url = serve(args.model)
    try:
        outcomes, wall, idle_open = run_load(url, args, frames)
    finally:
        process.kill()
        process.wait(timeout=30)
    reasons = collections.Counter(o.failure for o in outcomes if o.failure is not None)
    answered = [o.latency_s for o in outcomes if o.failure is None]
    record = Record(
        what="gva serve under concurrent clients, each its own connection sending predictions "
             "of rendered frames one after another, beside an idle client and a silent TCP "
             "socket; the server predicts one at a time",
        command=shlex.join(["python", "benchmarks/bench_serve_clients.py",
                            *(sys.argv[1:] if argv is None else argv)]),
        model=str(args.model), task=args.task, seed=args.seed, clients=args.clients,
        requests_per_client=args.requests, frames=args.frames, idle_client=True,
        silent_socket=True, answered=len(answered), failed=sum(reasons.values()),
        failures=tuple(Failures(r, n) for r, n in reasons.most_common()),
        latency=Latency.of(answered), wall_s=round(wall, 3), idle_client_open_at_end=idle_open,
        machine=Machine(os.cpu_count(), platform.python_version(), platform.platform(),
                        load_before, load_average(),
                        "clients and server share the machine's cores (loopback)"
                        + (f"; {args.note}" if args.note else "")))
    write_record(args.out, asdict(record), announce=False)
    expected = args.clients * args.requests
    latency = record.latency
    print(f"gva serve, {args.clients} clients x {args.requests} requests (+ an idle client, "
          f"a silent socket): {record.answered}/{expected} answered, {record.failed} failed"
          + (f", median {latency.median_s:.3f} s, p95 {latency.p95_s:.3f} s, "
             f"max {latency.max_s:.3f} s" if latency else "")
          + f", wall {record.wall_s:.1f} s, load {load_before[0]:.2f} on {os.cpu_count()} "
          f"cores -> {args.out}")
    return 0 if record.answered == expected and record.failed == 0 else 1


if __name__ == "__main__":
    raise SystemExit(main())
