"""Whether a model holds its answer while the arm comes into view, judged offline (issue 36).

    python studies/check_arm_mask_offline.py \
        --case unmasked runs/t36/s0/checkpoints/kqv/single runs/t36-mask/single-test-unmasked.gva \
        --case masked runs/t36-mask/kqv-single-masked runs/t36-mask/single-test-masked.gva \
        --masks runs/t36-mask/single-test-masked.gva \
        [--json benchmarks/results/arm_mask_offline.json]

A closed-loop pick re-targets the arm when a re-prediction's grasp lies more than
``LoopSettings.move_threshold_m`` from the one it follows, or turns more than
``turn_threshold_deg``. On a target that does not move, every such re-target is noise. A test
dataset collected with ``gva collect --stream test --approach-hz HZ`` holds, per scene, the
pick's first image and the images along the oracle's approach, all labelled with the same
grasp: this script predicts them all and reports, per case, how far each approach image's
grasp lies from the scene's first one (the re-targets the loop would make) and from the truth,
over all approach images and over those the loop heeds: where the frame shows all of the
footprint about the grasp followed (``LoopSettings.footprint_radius_m``). The robot's pixels
are read from ``--masks``, a dataset of the same scenes collected with the arm masked out (its
approach images have no depth and one colour there; the scenes and the arm's motion are the
same whatever the model reads). Offline, in minutes, before any closed-loop trial; the trials
have the last word.
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import asdict, dataclass
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

import numpy as np
from results_file import write_record

from harness.inputs.collector import APPROACH_MASKED_KEY
from perception.camera import RgbdFrame
from perception.labels import split_label
from perception.learning.data import Dataset
from perception.learning.dataset_file import load_dataset
from perception.learning.evaluate import predict_dataset
from perception.learning.learnable import ModelSpec
from perception.registry import load_model
from sim.trials.closed_loop.loop_settings import LoopSettings
from sim.trials.closed_loop.view import hidden_share
from sim.trials.pick_results import grasp_angle_rad


@dataclass(frozen=True)
class HoldResult:
    """One case: a checkpoint's predictions on one test dataset's pick and approach images.

    Shifts are from the scene's first (pick) image's grasp; errors from the truth [cm, deg].
    """

    case: str
    checkpoint: str
    dataset: str
    scenes: int
    approach_images: int
    pick_mean_error_cm: float
    approach_median_error_cm: float
    approach_p90_error_cm: float
    approach_median_shift_cm: float
    approach_p95_shift_cm: float
    moved_beyond_threshold_fraction: float
    turned_beyond_threshold_fraction: float
    retarget_fraction: float
    scenes_with_a_retarget: int
    heeded_images: int
    heeded_retarget_fraction: float
    heeded_p95_shift_cm: float
    scenes_with_a_heeded_retarget: int

    def line(self) -> str:
        """One line of the table this script prints."""
        return (f"{self.case:<12} pick error {self.pick_mean_error_cm:5.2f} cm | approach: "
                f"error median {self.approach_median_error_cm:5.2f}, p90 "
                f"{self.approach_p90_error_cm:5.2f} cm; shift median "
                f"{self.approach_median_shift_cm:5.2f}, p95 {self.approach_p95_shift_cm:5.2f} cm; "
                f"re-target {100 * self.retarget_fraction:4.1f} % of {self.approach_images} "
                f"images (moved {100 * self.moved_beyond_threshold_fraction:4.1f} %, turned "
                f"{100 * self.turned_beyond_threshold_fraction:4.1f} %), in "
                f"{self.scenes_with_a_retarget}/{self.scenes} scenes | heeded "
                f"{self.heeded_images}: re-target {100 * self.heeded_retarget_fraction:4.1f} %, "
                f"shift p95 {self.heeded_p95_shift_cm:5.2f} cm, in "
                f"{self.scenes_with_a_heeded_retarget}/{self.scenes} scenes")


def robot_masks(masked: Dataset) -> np.ndarray:
    """(N, H, W) bool: the robot's pixels in each image of ``masked``.

    ``masked`` was collected with the arm masked out: its approach images have no depth and one
    colour there; a pick's first image has none.
    """
    if not masked.metadata.extra.get(APPROACH_MASKED_KEY) or masked.depths_m is None:
        raise ValueError("--masks: a dataset collected with --approach-hz by a gva that masks "
                         f"the arm out ({APPROACH_MASKED_KEY}), with its depth images")
    masks = np.zeros(masked.depths_m.shape, bool)
    for index, (image, depth) in enumerate(zip(masked.images, masked.depths_m, strict=True)):
        blank = depth == 0.0
        if masked.scenes[index].get("stage") != "approach" or not blank.any():
            continue
        colours, counts = np.unique(image[blank], axis=0, return_counts=True)
        masks[index] = blank & (image == colours[counts.argmax()]).all(axis=-1)
    return masks


def hold(case: str, checkpoint: Path, dataset_path: Path, masks: np.ndarray) -> HoldResult:
    """How ``checkpoint``'s grasp moves along the approaches of ``dataset_path``'s scenes."""
    dataset = load_dataset(dataset_path)
    if masks.shape[0] != len(dataset):
        raise ValueError(f"--masks has {masks.shape[0]} images, {dataset_path} {len(dataset)}: "
                         "not the same scenes")
    camera = ModelSpec.from_metadata(dataset.metadata).camera
    if camera is None:
        raise ValueError(f"{dataset_path} records no camera: a yumi dataset does")
    predictions = predict_dataset(load_model(checkpoint), dataset)
    loop = LoopSettings()
    truth = split_label(dataset.labels[:, 0].astype(np.float64)).position_m
    pick_errors, errors, shifts, turns, retarget_scenes = [], [], [], [], set()
    heeded: list[bool] = []
    heeded_scenes = set()
    first: tuple[np.ndarray, np.ndarray] | None = None
    for index, (record, prediction) in enumerate(zip(dataset.scenes, predictions, strict=True)):
        target = prediction.targets[0]
        position, rotation = np.asarray(target.position_m), np.asarray(target.rotation)
        error_cm = 100 * float(np.linalg.norm(position - truth[index]))
        if record.get("stage", "pick") == "pick":
            first = (position, rotation)
            pick_errors.append(error_cm)
            continue
        if first is None:
            raise ValueError(f"{dataset_path}: approach image {index} before any pick image")
        errors.append(error_cm)
        shifts.append(100 * float(np.linalg.norm(position - first[0])))
        turns.append(math.degrees(grasp_angle_rad(first[1], rotation)))
        frame = RgbdFrame(dataset.images[index], np.zeros(masks.shape[1:], np.float32), camera,
                          robot_mask=masks[index])
        heeded.append(hidden_share(frame, first[0], loop.footprint_radius_m) == 0.0)
        if (shifts[-1] > 100 * loop.move_threshold_m or turns[-1] > loop.turn_threshold_deg):
            retarget_scenes.add(record["index"])
            if heeded[-1]:
                heeded_scenes.add(record["index"])
    if not errors:
        raise ValueError(f"{dataset_path} has no approach images: collect it with --approach-hz")
    shift, turn = np.asarray(shifts), np.asarray(turns)
    moved = shift > 100 * loop.move_threshold_m
    turned = turn > loop.turn_threshold_deg
    seen = np.asarray(heeded)
    return HoldResult(
        case=case, checkpoint=str(checkpoint), dataset=str(dataset_path),
        scenes=len(pick_errors), approach_images=len(errors),
        pick_mean_error_cm=float(np.mean(pick_errors)),
        approach_median_error_cm=float(np.median(errors)),
        approach_p90_error_cm=float(np.percentile(errors, 90)),
        approach_median_shift_cm=float(np.median(shift)),
        approach_p95_shift_cm=float(np.percentile(shift, 95)),
        moved_beyond_threshold_fraction=float(moved.mean()),
        turned_beyond_threshold_fraction=float(turned.mean()),
        retarget_fraction=float((moved | turned).mean()),
        scenes_with_a_retarget=len(retarget_scenes), heeded_images=int(seen.sum()),
        heeded_retarget_fraction=float((moved | turned)[seen].mean()) if seen.any() else 0.0,
        heeded_p95_shift_cm=float(np.percentile(shift[seen], 95)) if seen.any() else 0.0,
        scenes_with_a_heeded_retarget=len(heeded_scenes))


def main(argv: list[str] | None = None) -> int:
    """Prints each case's line; with ``--json``, writes them with the command."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[1],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--case", nargs=3, action="append", required=True,
                        metavar=("NAME", "CHECKPOINT", "DATASET"),
                        help="a name, a checkpoint folder and a test dataset with approach images")
    parser.add_argument("--masks", type=Path, required=True,
                        help="a dataset of the same scenes collected with the arm masked out")
    parser.add_argument("--json", type=Path, help="file to write the results to")
    args = parser.parse_args(argv)
    masks = robot_masks(load_dataset(args.masks))
    results = [hold(name, Path(checkpoint), Path(data), masks)
               for name, checkpoint, data in args.case]
    for result in results:
        print(result.line())
    if args.json is not None:
        write_record(args.json, {
            "command": "python studies/check_arm_mask_offline.py " + " ".join(
                sys.argv[1:] if argv is None else argv),
            "loop": LoopSettings().to_json(),
            "results": [asdict(r) for r in results]}, announce=False)
    return 0


if __name__ == "__main__":
    sys.exit(main())
