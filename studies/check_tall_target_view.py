"""How often a closed loop would re-target a moved-target pick onto a grasp that misses, offline.

Issue 66: ``kqv`` lost moved spray bottles that the view-limited oracle picks; its trial records
show the grasp drifting 1-3 cm as the hand nears a bottle. This drives the oracle's closed loop
over a task's TEST scenes (the collector's demonstrations, every approach image kept with its
robot mask), predicts each image with each checkpoint, and reports per target type:

- the grasp error by what the image shows: the 4.5 cm footprint and the target's whole column
  (the same disk from the table to the object's top) both seen, the footprint seen but some of
  the column hidden (a tall bottle behind the hand: the first guess, not borne out), the
  footprint hidden;
- the looks the loop would heed (the footprint seen, or the grasp named in plain view two looks
  in a row, :func:`sim.trials.closed_loop.view.unheeded_reason`) whose grasp is off the truth by
  more than the re-target thresholds and judged missed: a re-target onto a miss, and the scenes
  with one.

    python studies/check_tall_target_view.py --task single-moved --seed 0 --scenes 60 \
        runs/cl66/s0/checkpoints/kqv/single-moved [CHECKPOINT ...]
"""

from __future__ import annotations

import argparse
import collections
import math
from dataclasses import dataclass, field

import numpy as np

from harness.inputs.collector import CollectSettings
from perception.camera import RgbdFrame
from perception.interface import Condition, Prediction
from perception.judge.grasp_judge import judge_grasp, yaw_of
from perception.objects.catalog import get_object_spec
from perception.poses import Pose
from perception.registry import load_model
from sim.tasks.scene_sampling import SeedStream, sample_scene
from sim.tasks.scene_specs import get_scene_spec
from sim.trials.closed_loop.loop_settings import Loop, LoopSettings
from sim.trials.closed_loop.view import hidden_share, unheeded_reason
from sim.trials.pick_results import grasp_angle_rad
from sim.trials.trial_runner import TrialRunner

LEVELS = 5
"""Disks looked at from the table to the object's top (the column's share is their worst)."""


@dataclass(frozen=True)
class Look:
    """One approach image of a target, with what it shows of it."""

    scene: int
    frame: RgbdFrame
    given: Condition
    object_type: str
    truth: Pose
    object_yaw_rad: float
    footprint_hidden: float
    column_hidden: float


def column_hidden_share(frame: RgbdFrame, grasp_m: np.ndarray, top_m: float,
                        radius_m: float) -> float:
    """The worst hidden share of the level disks about ``grasp_m`` from the table to ``top_m``."""
    return max(hidden_share(frame, np.array([grasp_m[0], grasp_m[1], z]), radius_m)
               for z in np.linspace(0.005, top_m, LEVELS))


class _Watcher:
    """Keeps every re-prediction's frame of a pick's approach (a TrialObserver)."""

    def __init__(self, runner: TrialRunner, radius_m: float) -> None:
        self.runner, self.radius_m = runner, radius_m
        self.looks: list[Look] = []
        self.body: int | None = None
        self.given: Condition | None = None
        self.scene = -1

    def saw(self, frame: RgbdFrame, prediction: Prediction | None) -> None:
        if frame.robot_mask is None or self.body is None or self.given is None:
            return  # the pick's own image, the arm at home
        spec = self.runner.world.object_spec(self.body)
        truth, pose = self.runner.truth(self.body), self.runner.world.object_pose(self.body)
        top_m = float(pose.position[2]) + spec.height_m
        self.looks.append(Look(self.scene, frame, self.given, spec.name, truth,
                               yaw_of(pose.rotation),
                               hidden_share(frame, truth.position, self.radius_m),
                               column_hidden_share(frame, truth.position, top_m, self.radius_m)))

    def stepped(self, world: object) -> None:
        """Nothing to watch between images."""


def _pose(prediction: Prediction) -> Pose:
    target = prediction.targets[0]
    return Pose(np.asarray(target.position_m), np.asarray(target.rotation))


@dataclass
class Tally:
    """What a checkpoint's grasps came to, per target type.

    (error [cm], judged picked) by view class; the looks heeded; the re-targets onto a grasp
    judged missed, and the scenes they fell in.
    """

    errors: dict[tuple[str, str], list[tuple[float, float]]] = field(
        default_factory=lambda: collections.defaultdict(list))
    heeded: collections.Counter[str] = field(default_factory=collections.Counter)
    wrong: collections.Counter[str] = field(default_factory=collections.Counter)
    wrong_scenes: dict[str, set[int]] = field(default_factory=lambda: collections.defaultdict(set))
    scenes: dict[str, set[int]] = field(default_factory=lambda: collections.defaultdict(set))


def tally_looks(looks: list[Look], predicted: list[Pose], loop: LoopSettings) -> Tally:
    """What the loop would make of each look's predicted grasp, the truth followed.

    The oracle drove, so the grasp followed is the truth; a look is heeded as the loop heeds it
    (:func:`~sim.trials.closed_loop.view.unheeded_reason`, two looks in a row within a scene for the
    plain-view clause), and it is a wrong re-target where its grasp is beyond the thresholds
    from the truth and the grasp judge predicts it missed.
    """
    tally, once, scene = Tally(), None, None
    for look, grasp in zip(looks, predicted, strict=True):
        error_cm = 100 * float(np.linalg.norm(grasp.position - look.truth.position))
        judged = judge_grasp(get_object_spec(look.object_type), look.truth, grasp,
                             look.object_yaw_rad).predicted_success
        view = ("footprint hidden" if look.footprint_hidden > 0 else
                "column seen" if look.column_hidden == 0 else "column partly hidden")
        tally.errors[(look.object_type, view)].append((error_cm, float(judged)))
        tally.scenes[look.object_type].add(look.scene)
        verdict = unheeded_reason(look.frame, look.truth.position, grasp.position,
                                  loop.footprint_radius_m, once if scene == look.scene else None,
                                  loop.move_threshold_m)
        once, scene = verdict.unconfirmed_m, look.scene
        if verdict.unheeded is not None:
            continue
        tally.heeded[look.object_type] += 1
        off = error_cm > 100 * loop.move_threshold_m or math.degrees(grasp_angle_rad(
            look.truth.rotation, grasp.rotation)) > loop.turn_threshold_deg
        if off and not judged:
            tally.wrong[look.object_type] += 1
            tally.wrong_scenes[look.object_type].add(look.scene)
    return tally


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="single-moved")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--scenes", type=int, default=20)
    parser.add_argument("checkpoints", nargs="+")
    args = parser.parse_args()
    settings = CollectSettings("yumi", args.task, args.scenes, args.seed, SeedStream.TEST,
                               approach_hz=10.0)
    task, spec = settings.task_spec, get_scene_spec("yumi")
    loop = LoopSettings(Loop.CLOSED, 10.0)
    with TrialRunner(task, loop=loop, robot=settings.description()) as runner:
        watcher = _Watcher(runner, loop.footprint_radius_m)
        runner.observer = watcher
        for index in range(args.scenes):
            scene = sample_scene(task, spec, args.seed, SeedStream.TEST, index)
            bodies = runner.setup(scene)
            watcher.body, watcher.given = bodies[scene.targets[0]], scene.given
            watcher.scene = index
            runner.pick_targets(scene, bodies)
    print(f"{len(watcher.looks)} approach images of {args.scenes} scenes")
    for checkpoint in args.checkpoints:
        model = load_model(checkpoint)
        tally = tally_looks(watcher.looks, [_pose(model.predict_frame(look.frame, look.given))
                                            for look in watcher.looks], loop)
        print(checkpoint)
        for (kind, view), rows in sorted(tally.errors.items()):
            e, j = np.asarray(rows).T
            print(f"  {kind:<13} {view:<21} n {len(e):4d}  median {np.median(e):5.2f} cm  "
                  f"p90 {np.percentile(e, 90):5.2f}  > 1 cm {100 * (e > 1).mean():4.0f} %  "
                  f"judged picked {100 * j.mean():4.0f} %")
        print("  heeded looks that would re-target onto a grasp judged missed: " + ", ".join(
            f"{kind} {tally.wrong[kind]}/{tally.heeded[kind]} (scenes "
            f"{len(tally.wrong_scenes[kind])}/{len(tally.scenes[kind])})"
            for kind in sorted(tally.heeded)))


if __name__ == "__main__":
    main()
