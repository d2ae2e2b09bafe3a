"""The ``gva`` command line.

    gva collect --scene yumi --task multiple --size 20 --seed 0 --out runs/yumi-multiple-20.gva
    gva collect --scene yumi --task multiple --size 100 --seed 1 --out runs/yumi-multiple-test.gva
    gva train --model kqv --data runs/yumi-multiple-20.gva --out runs/kqv-multiple
    gva evaluate --model runs/kqv-multiple --data runs/yumi-multiple-test.gva
    gva trials --model oracle --task single --n 30 --seed 0 --out runs/oracle-single
    gva trials --model runs/kqv-multiple --task multiple --n 30 --out runs/kqv-multiple-trials
    gva serve runs/kqv-multiple --port 8000
    gva trials --model ws://127.0.0.1:8000 --task multiple --n 30 --out runs/kqv-served
    gva compare runs/oracle-single runs/kqv-single-trials --out runs/kqv-vs-oracle.json
    gva judge runs/table3 --json runs/table3-judged.json
    gva export --format lerobot runs/yumi-multiple-20.gva runs/yumi-multiple-20-lerobot
    gva import runs/yumi-multiple-20-lerobot runs/yumi-multiple-20-again.gva
    gva show scene --scene paper-sim --task multiple --out runs/scene.png
    gva show attention --model runs/kqv-multiple --data runs/yumi-multiple-20.gva --out runs/att
    gva reproduce sim --out runs/table2 --seeds 3 --models kqv,fcn --tasks single --sizes 4,20
    gva reproduce real --out runs/table3 --models kqv,keypoint-16,fcn

``train`` takes a registered model, a preset (``keypoint-16``) or ``package.module:Class``;
``evaluate``, ``show attention`` and ``trials`` take a checkpoint folder, with
``--model-class package.module:Class`` for a model that is not registered. ``trials`` also
takes ``oracle`` or ``package.module:Class`` of a model that needs no weights.

``compare`` pairs two finished runs of ``trials`` on the same trial list (task, seed, n): exact
McNemar test and the difference in success rate with its interval (:mod:`harness.compare`);
it exits with status 1 when the second run is significantly worse than the first.

``reproduce sim`` and ``reproduce real`` run the paper's Tables II and III
(:mod:`experiments.table2`, :mod:`experiments.table3`, ``docs/reproducing.md``); each exits
with status 1 when it finished but some of its jobs failed (each failure is recorded).

Bad input exits with status 2 and one line naming the value and what is allowed; a run that
stops half-way (``trials``, ``reproduce sim``, ``reproduce real``) is resumed by running the
same command again. Each command's options and what it prints live in its module of
:mod:`experiments.commands`; this module lists the commands and reports their errors.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Callable, Sequence
from functools import partial
from typing import Any

from control.errors import ControlError
from experiments.commands.arguments import resume_command
from perception.interface import PerceptionError
from sim.errors import SimError

Options = Callable[[argparse.ArgumentParser], None]


class _Command(argparse.ArgumentParser):
    """A command whose options are added when it is parsed, by a function of its own module.

    The options' defaults come from settings dataclasses whose modules import pinocchio or
    torch; added on demand, ``gva --help`` imports none of them and each command only its own.
    """

    def __init__(self, *args: Any, options: Options | None = None, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._options = options

    def parse_known_args(  # type: ignore[override]  # one signature for typeshed's overloads
            self, args: Sequence[str] | None = None, namespace: Any = None
    ) -> tuple[Any, list[str]]:
        """Adds the command's options (the first time), then parses as argparse does."""
        if self._options is not None:
            add, self._options = self._options, None
            add(self)
        return super().parse_known_args(args, namespace)


# Each function below imports the module of its command(s) only when one is parsed.


def _trials(parser: argparse.ArgumentParser) -> None:
    from experiments.commands.trials import add_options  # pinocchio: not for `gva --help`

    add_options(parser)


def _serve(parser: argparse.ArgumentParser) -> None:
    from experiments.commands.serve import add_options  # websockets: only here

    add_options(parser)


def _compare(parser: argparse.ArgumentParser) -> None:
    from experiments.commands.compare import add_options  # scipy.stats: only here

    add_options(parser)


def _judge(parser: argparse.ArgumentParser) -> None:
    from experiments.commands.judge import add_options  # numpy only: no torch, no physics

    add_options(parser)


def _collect(parser: argparse.ArgumentParser) -> None:
    from experiments.commands.collect import add_options  # torch: not for `gva trials`

    add_options(parser)


def _export(parser: argparse.ArgumentParser) -> None:
    from experiments.commands.export import add_export_options  # pyarrow: only here

    add_export_options(parser)


def _import(parser: argparse.ArgumentParser) -> None:
    from experiments.commands.export import add_import_options  # pyarrow: only here

    add_import_options(parser)


def _scene(parser: argparse.ArgumentParser) -> None:
    from experiments.commands.scene import add_options  # pinocchio: not for `gva --help`

    add_options(parser)


def _model_command(command: str, parser: argparse.ArgumentParser) -> None:
    from experiments.commands.models import add_options  # torch: not for `gva trials`

    add_options(parser, command)


def _table2(parser: argparse.ArgumentParser) -> None:
    from experiments.commands.table2 import add_options  # torch and matplotlib: only here

    add_options(parser)


def _table3(parser: argparse.ArgumentParser) -> None:
    from experiments.commands.table3 import add_options  # torch: not for `gva --help`

    add_options(parser)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of every ``gva`` command (each adds its options when parsed)."""
    parser = argparse.ArgumentParser(
        prog="gva", description="Guided visual attention: YuMi pick trials in PyBullet."
    )
    commands = parser.add_subparsers(dest="command", required=True, parser_class=_Command)
    commands.add_parser(
        "trials", options=_trials,
        help="pick trials at untrained positions",
        description="Runs pick trials: reset a scene from the seed, predict, plan, execute, "
        "judge by physics. Appends each trial to OUT/trials.jsonl; re-running resumes.",
    )
    commands.add_parser(
        "serve", options=_serve,
        help="serve a model over a websocket (openpi-client's protocol) for --model ws://",
        description="Serves a checkpoint or a plug-in model over a websocket in openpi-client "
        "0.1.2's WebsocketClientPolicy protocol: metadata on connect, a msgpack request per "
        "frame, the prediction back, an error as a text frame. gva trials --model "
        "ws://HOST:PORT picks with it. Serves until Ctrl-C.",
    )
    commands.add_parser(
        "compare", options=_compare,
        help="two runs of trials on the same trials, compared pair by pair (is B worse?)",
        description="Pairs the trials of two finished runs of gva trials (same task, seed and "
        "n) by index: the pairs of outcomes, the exact McNemar test, the difference in success "
        "rate B - A with its interval (Newcombe's, for paired data), overall and per "
        "object type. Exit status 1 when B is significantly worse than A, else 0.",
    )
    commands.add_parser(
        "judge", options=_judge,
        help="a run's picks replayed through the grasp judge, beside the physics",
        description="Judges every pick of a run folder (gva trials or gva reproduce real, "
        "also one made before the judge existed) without physics: its error in the grasp's "
        "frame against each object's measured tolerance. Prints per task and seed the real and "
        "the predicted count, and over all picks the misses, those it flagged, those it did "
        "not and its false alarms.",
    )
    commands.add_parser(
        "collect", options=_collect,
        help="collect a training dataset (yumi: oracle demonstrations kept when they succeed)",
        description="Collects SIZE scenes of a task into one dataset file: training scenes, "
        "or untrained test scenes with --stream test.",
    )
    commands.add_parser(
        "export", options=_export,
        help="a dataset file as a LeRobotDataset v3.0 folder (--format lerobot)",
        description="Writes a .gva dataset as a LeRobotDataset v3.0 folder: one episode per "
        "scene, PNG images in parquet, the grasp labels as action; what LeRobot has no column "
        "for in meta/gva.json, so that gva import gives back the same dataset.",
    )
    commands.add_parser(
        "import", options=_import,
        help="a LeRobot folder gva export wrote, back into a dataset file",
        description="Reads a folder of gva export --format lerobot back into a .gva dataset "
        "file, checked byte for byte against the checksum the export recorded.",
    )
    commands.add_parser(
        "train", options=partial(_model_command, "train"),
        help="train a perception model on a dataset and save its checkpoint",
        description="Trains a fresh model on a dataset and writes its checkpoint folder.",
    )
    commands.add_parser(
        "evaluate", options=partial(_model_command, "evaluate"),
        help="a checkpoint's errors on a dataset, as the paper reports them",
        description="Mean position error in cm (angle errors too for grasp labels) of a "
        "checkpoint on a dataset; writes them as JSON.",
    )
    show = commands.add_parser("show", help="pictures of what the models see")
    shown = show.add_subparsers(dest="what", required=True, parser_class=_Command)
    shown.add_parser(
        "scene", options=_scene,
        help="a scene as its camera sees it, as a PNG",
        description="Renders scene INDEX of a task's training or test stream.",
    )
    shown.add_parser(
        "attention", options=partial(_model_command, "attention"),
        help="a checkpoint's attention points and heatmaps, as PNGs (Fig. 5)",
        description="For each of the first COUNT samples of a dataset: the image with the "
        "attention points, and each head's heatmap; a conditioned model gets one row per "
        "condition choice.",
    )
    reproduce = commands.add_parser("reproduce", help="the paper's experiments, end to end")
    experiments = reproduce.add_subparsers(dest="experiment", required=True,
                                           parser_class=_Command)
    experiments.add_parser(
        "sim", options=_table2,
        help="Table II: position error of every model in the simulator",
        description="Collects paper-sim datasets, trains every model x task x size x seed "
        "cell in parallel processes, scores each on its task's untrained test scenes and writes "
        "OUT/table2.md, table2.json, table2.png and fig5.png. Re-running skips finished cells.",
    )
    experiments.add_parser(
        "real", options=_table3,
        help="Table III: YuMi pick trials out of 30 with trained models in the loop",
        description="Per task on the yumi scene: collects oracle-verified demonstrations, "
        "trains each model on them, runs pick trials at untrained positions with "
        "the trained model in the loop (each model also under each --variants: darker light "
        "and the block by default), "
        "each seed in OUT/s<seed>/, and writes OUT/table3.md and table3.json over the seeds "
        "and OUT/s<seed>/gifs/<model>-<task>.gif. Re-running skips what is finished.",
    )
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``gva`` command; returns the exit status."""
    argv = list(sys.argv[1:] if argv is None else argv)
    args = build_parser().parse_args(argv)
    args.argv = argv  # the command line, for the resume hint
    name = f"reproduce {args.experiment}" if args.command == "reproduce" else args.command
    try:
        status: int = args.run(args)  # the command's own (its options set it)
    except BrokenPipeError:  # the reader went away (``gva evaluate ... | head``): not an error
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # no flush error at exit
        return 0
    except (SimError, ControlError, PerceptionError, ValueError, OSError) as error:
        print(f"gva {name}: error: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as interrupt:  # a bare Ctrl-C has no message: say how to resume
        hint = str(interrupt) or f"resume with: {resume_command(args)}"
        print(f"gva {name}: interrupted; {hint}", file=sys.stderr)
        return 130
    return status


if __name__ == "__main__":
    sys.exit(main())
