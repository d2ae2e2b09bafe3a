"""The ``gva`` command line.

    gva trials --model oracle --task single --n 30 --seed 0 --out runs/oracle-single
    gva collect --scene yumi --task multiple --size 20 --seed 0 --out runs/yumi-multiple-20.gva
    gva show scene --scene paper-sim --task multiple --out runs/scene.png

Bad input exits with status 2 and one line naming the value and what is allowed; a run that
stops half-way is resumed by running the same command again.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

from control.errors import ControlError
from perception.interface import PerceptionError
from sim.errors import SimError


def _integer(minimum: int) -> Callable[[str], int]:
    """An argparse type: an integer >= ``minimum``, with a message that says so."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"{value} is not allowed: an integer >= {minimum}")
        return value

    return parse


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of every ``gva`` sub-command."""
    parser = argparse.ArgumentParser(
        prog="gva", description="Guided visual attention: YuMi pick trials in PyBullet."
    )
    commands = parser.add_subparsers(dest="command", required=True)
    trials = commands.add_parser(
        "trials",
        help="closed-loop pick trials at untrained positions",
        description="Runs pick trials: reset a scene from the seed, predict, plan, execute, "
        "judge by physics. Appends each trial to OUT/trials.jsonl; re-running resumes.",
    )
    trials.add_argument("--model", default="oracle", help="perception model (default: oracle)")
    trials.add_argument("--task", default="single",
                        help="built-in task name or task TOML path (default: single)")
    trials.add_argument("--n", type=_integer(1), default=30, help="number of trials (30)")
    trials.add_argument("--seed", type=_integer(0), default=0, help="seed of the test scenes (0)")
    trials.add_argument("--out", type=Path, required=True, help="run folder")
    trials.add_argument("--no-progress", action="store_true", help="no progress bar")

    collect = commands.add_parser(
        "collect",
        help="collect a training dataset (yumi: oracle demonstrations kept when they succeed)",
        description="Collects SIZE training scenes of a task into one dataset file.",
    )
    collect.add_argument("--scene", required=True, help="paper-sim or yumi")
    collect.add_argument("--task", required=True, help="built-in task name or task TOML path")
    collect.add_argument("--size", type=_integer(1), required=True, help="training scenes")
    collect.add_argument("--seed", type=_integer(0), default=0, help="training seed (0)")
    collect.add_argument("--out", type=Path, required=True, help="dataset file to write")
    collect.add_argument("--no-progress", action="store_true", help="no progress bar")

    show = commands.add_parser("show", help="pictures of what the models see")
    shown = show.add_subparsers(dest="what", required=True)
    scene = shown.add_parser(
        "scene", help="a scene as its camera sees it, as a PNG",
        description="Renders scene INDEX of a task's training or test stream.",
    )
    scene.add_argument("--scene", required=True, help="paper-sim or yumi")
    scene.add_argument("--task", default="multiple", help="task name or TOML path (multiple)")
    scene.add_argument("--seed", type=_integer(0), default=0, help="seed (0)")
    scene.add_argument("--index", type=_integer(0), default=0, help="scene index (0)")
    scene.add_argument("--stream", choices=("train", "test"), default="test",
                       help="seed stream (test)")
    scene.add_argument("--scale", type=_integer(1), default=1,
                       help="enlarge the PNG this many times (1: the model's size)")
    scene.add_argument("--out", type=Path, required=True, help="PNG file to write")
    return parser


def _run_trials(args: argparse.Namespace) -> int:
    from sim.trials import TrialSettings, run_trials

    settings = TrialSettings(model=args.model, task=args.task, n=args.n, seed=args.seed)
    summary = run_trials(settings, args.out, progress=not args.no_progress)
    print(summary.headline())
    for outcome, count in summary.outcomes.items():
        if count:
            print(f"  {outcome:<18} {count}")
    picked = ", ".join(f"{name} {c['picked']}/{c['attempted']}"
                       for name, c in summary.per_object.items())
    print(f"picks by object: {picked}")
    print(f"median wall time per trial: {summary.median_wall_time_s:.2f} s")
    print(f"trials: {args.out / 'trials.jsonl'}   summary: {args.out / 'summary.json'}")
    return 0


def _run_collect(args: argparse.Namespace) -> int:
    from sim.collect import CollectSettings, collect

    settings = CollectSettings(scene=args.scene, task=args.task, size=args.size, seed=args.seed)
    dataset = collect(settings, args.out, progress=not args.no_progress)
    meta = dataset.metadata
    redrawn = meta.extra.get("demonstrations_redrawn")
    print(f"{meta.size} scenes of {meta.scene} / {meta.task} (seed {meta.seed}), "
          f"{meta.targets} target(s) each, {meta.label_kind.value} labels"
          + (f"; {redrawn} failed demonstrations redrawn" if redrawn is not None else ""))
    print(f"dataset: {args.out}")
    return 0


def _run_show(args: argparse.Namespace) -> int:
    from sim.scene import SeedStream, sample_scene
    from sim.scenes import get_scene_spec
    from sim.show import render_scene, write_scene_png
    from sim.tasks import load_task

    task = load_task(args.task)
    stream = SeedStream.TRAIN if args.stream == "train" else SeedStream.TEST
    scene = sample_scene(task, get_scene_spec(args.scene), args.seed, stream, args.index)
    image = render_scene(scene, task.brightness)
    path = write_scene_png(image, args.out, args.scale)
    targets = ", ".join(scene.objects[i].object_type for i in scene.targets)
    condition = f"; condition {scene.condition.value}" if scene.condition.value else ""
    print(f"{args.scene} / {task.name}, {args.stream} scene {args.index}: targets {targets}"
          f"{condition}; {image.shape[1]}x{image.shape[0]} px image")
    print(f"wrote {path}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``gva`` command; returns the exit status."""
    args = build_parser().parse_args(argv)
    try:
        if args.command == "trials":
            return _run_trials(args)
        if args.command == "collect":
            return _run_collect(args)
        if args.command == "show":
            return _run_show(args)
    except (SimError, ControlError, PerceptionError, ValueError) as error:
        print(f"gva {args.command}: error: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"gva {args.command}: interrupted; run the same command again to resume",
              file=sys.stderr)
        return 130
    raise AssertionError(f"unhandled command {args.command}")  # argparse rejects others


if __name__ == "__main__":
    sys.exit(main())
