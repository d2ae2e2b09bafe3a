"""``gva show scene``: a scene of a task's training or test stream, as its camera sees it."""

from __future__ import annotations

import argparse
from pathlib import Path

from experiments.commands.arguments import Once, add_sensor_option, integer, sensor_kind
from experiments.commands.pick_options import ROBOT
from harness.inputs.collector import CollectSettings
from perception.interface import ConditionKind
from sim.tasks.scene_picture import render_scene, write_scene_png
from sim.tasks.scene_sampling import SeedStream
from sim.tasks.scene_specs import get_scene_spec


def add_options(parser: argparse.ArgumentParser) -> None:
    """The options of ``gva show scene``."""
    parser.add_argument("--scene", required=True, help="paper-sim or yumi")
    parser.add_argument("--task", default="multiple",
                        help="task name or TOML path (%(default)s)")
    parser.add_argument("--variant", metavar="NAME|FILE", action=Once,
                        help="the task under a variant of its looks (docs/tasks.md)")
    parser.add_argument("--seed", type=integer(0), default=0, help="seed (%(default)s)")
    parser.add_argument("--index", type=integer(0), default=0, help="scene index (%(default)s)")
    parser.add_argument("--stream", choices=[stream.name.lower() for stream in SeedStream],
                        default="test", help="seed stream (%(default)s)")
    parser.add_argument("--scale", type=integer(1), default=1,
                        help="enlarge the PNG this many times (%(default)s: the model's size)")
    add_sensor_option(parser)
    ROBOT.add_to(parser, CollectSettings.robot)
    parser.add_argument("--out", type=Path, required=True, help="PNG file to write")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Renders the scene, writes the PNG and says what it shows; the exit status.

    The scene is the one ``gva collect`` would demonstrate at this index (its settings' task:
    sensor, variant, the robot's spacing), so the picture is that demonstration's first image.
    """
    stream = SeedStream[args.stream.upper()]
    settings = CollectSettings(args.scene, args.task, args.index + 1, args.seed, stream,
                               robot=args.robot, variant=args.variant, sensor=sensor_kind(args))
    task = settings.task_spec
    scene = settings.scene_at(task, get_scene_spec(args.scene), args.index)
    image = render_scene(scene, task, settings.description())
    path = write_scene_png(image, args.out, args.scale)
    targets = ", ".join(scene.objects[i].object_type for i in scene.targets)
    condition = f"; condition {scene.condition.value}" if scene.condition.value else ""
    if scene.query is not None:  # what the model is given for it
        condition += (f', asked as "{scene.query.value}"' if scene.query.kind is
                      ConditionKind.TEXT else f", shown as a {scene.query.value}")
    through = "its own ideal camera" if args.scene == "paper-sim" else \
        f"the {task.sensor.kind.value} sensor"
    print(f"{args.scene} / {task.name}, {args.stream} scene {args.index}: targets {targets}"
          f"{condition}; {image.shape[1]}x{image.shape[0]} px image, seen through {through}")
    print(f"wrote {path}")
    return 0
