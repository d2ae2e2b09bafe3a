"""``gva collect``: a training or test dataset of a task, in one file.

Defaults are :class:`~harness.inputs.collector.CollectSettings`'.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from experiments.commands.arguments import Once, add_sensor_option, integer, sensor_kind
from harness.inputs.collector import CollectSettings, LabelSource, LookSource, collect
from perception.interface import ConditionKind, InvalidInputError
from robots import ROBOT_NAMES
from sim.tasks.scene_sampling import SeedStream
from sim.tasks.variants import builtin_variants


def add_options(parser: argparse.ArgumentParser) -> None:
    """The options of ``gva collect``."""
    parser.add_argument("--scene", required=True, help="paper-sim or yumi")
    parser.add_argument("--task", required=True, help="built-in task name or task TOML path")
    parser.add_argument("--variant", metavar="NAME|FILE", action=Once,
                        help="the task under a variant of its looks: one of "
                        f"{', '.join(builtin_variants())}, or a variant .toml file")
    parser.add_argument("--size", type=integer(1), required=True, help="number of scenes")
    parser.add_argument("--seed", type=integer(0), default=CollectSettings.seed,
                        help="seed of the scenes (%(default)s)")
    parser.add_argument("--stream", choices=[stream.name.lower() for stream in SeedStream],
                        default=CollectSettings.stream.name.lower(),
                        help="seed stream: train, or test for untrained scenes (%(default)s)")
    parser.add_argument("--every-condition", action=argparse.BooleanOptionalAction,
                        default=CollectSettings.every_condition,
                        help="a sample per condition value of each scene, each labelled with "
                        "the object that value names (default: for the train stream)")
    parser.add_argument("--approach-hz", type=float, metavar="HZ",
                        help="yumi: also keep an image every 1/HZ s of each approach, the arm "
                        "in view, labelled as the pick's (for closed-loop picks)")
    parser.add_argument("--robot", choices=ROBOT_NAMES, default=CollectSettings.robot,
                        help="yumi scene: the robot whose demonstrations these are, seen "
                        "through its workcell's camera (%(default)s)")
    add_sensor_option(parser)
    parser.add_argument("--labels", choices=[source.value for source in LabelSource],
                        default=CollectSettings.labels.value,
                        help="yumi: picked (demonstrations, each scene kept only if the oracle "
                        "picked every target in physics) or catalog (each scene settled and "
                        "seen as a trial's, labelled with the oracle's grasps, never picked: "
                        "hundreds a minute) (%(default)s)")
    parser.add_argument("--looks", choices=[source.value for source in LookSource],
                        default=CollectSettings.looks.value,
                        help="yumi: task (as the task and --variant say) or randomised (any "
                        "colour per part, the train half's prints, any table and lamp, "
                        "look-alikes in some scenes; never a held-out look) (%(default)s)")
    parser.add_argument("--out", type=Path, required=True,
                        help="dataset file to write (.gva; must not exist yet)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Collects the dataset and prints what it holds; the exit status."""
    out: Path = args.out
    if out.exists():  # before the collecting: a dataset already there is never replaced
        raise InvalidInputError("--out", str(out), "a .gva path that does not exist yet"
                                + ("; it is a folder" if out.is_dir() else ""))
    settings = CollectSettings(scene=args.scene, task=args.task, size=args.size, seed=args.seed,
                               stream=SeedStream[args.stream.upper()],
                               every_condition=args.every_condition,
                               approach_hz=args.approach_hz, robot=args.robot,
                               variant=args.variant, sensor=sensor_kind(args),
                               labels=LabelSource(args.labels), looks=LookSource(args.looks))
    dataset = collect(settings, args.out, progress=not args.no_progress)
    meta = dataset.metadata
    redrawn = meta.extra.get("demonstrations_redrawn")
    scenes = meta.extra.get("scenes", meta.size)
    why = ("one per condition value" if meta.extra.get("every_condition") and meta.targets == 1
           and meta.condition_kind is not ConditionKind.NONE else "one before each pick")
    approach = sum(record.get("stage") == "approach" for record in dataset.scenes)
    if approach:
        why += (f", {approach} along the approaches, one every "
                f"1/{meta.extra['approach_hz']:g} s where the arm hides no target; "
                f"{meta.extra.get('approach_images_hidden', 0)} where it does left out")
    images = f" ({meta.size} samples: {why})" if scenes != meta.size else ""
    sensor = meta.camera.get("sensor", {}).get("sensor", "ideal")
    print(f"{scenes} scenes{images} of {meta.scene} / {meta.task} (seed {meta.seed}, "
          f"{meta.extra.get('stream', args.stream)} stream, seen through the {sensor} sensor), "
          f"{meta.targets} target(s) each, {meta.label_kind.value} labels"
          + (f"; {redrawn} failed demonstrations redrawn" if redrawn is not None else "")
          + ("; labelled by the catalog, never picked"
             if meta.extra.get("labels") == LabelSource.CATALOG.value else "")
          + ("; randomised looks" if "looks" in meta.extra else ""))
    print(f"dataset: {args.out}")
    return 0
