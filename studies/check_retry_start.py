"""Study (issue 75): a held-out check's later start, trained again, plain or weighting what failed.

A checkpoint the held-out check refused at every start: is what failed its start (the weights'
first values and the batch order) or its data (too few samples of the part it failed on)? This
trains the unit's start ``--attempt`` exactly as :func:`~perception.learning.validation.
fit_checked` would (the same held-out scenes, the seed :func:`attempt_seed` gives, ``kqv`` with
its defaults), optionally with every kept sample that shows ``--twice`` (an object type) drawn
twice per epoch, checks it as the run checks, and saves it for ``gva trials``.

Usage:
    python studies/check_retry_start.py DATASET --seed 28 --attempt 3 [--twice sponge]
        --out CHECKPOINT [--steps 1000]

Answered in docs/decisions/any-seed.md ("The check after the bar run").
"""

from __future__ import annotations

import argparse
from dataclasses import replace

import numpy as np

from perception.learning.data import Dataset
from perception.learning.dataset_file import load_dataset
from perception.learning.judged_errors import judge_predictions
from perception.learning.train import TrainConfig
from perception.learning.validation import CheckConfig, attempt_seed, check_model, split_scenes
from perception.registry import new_model


def drawn_twice(dataset: Dataset, object_type: str) -> Dataset:
    """``dataset`` with each sample whose targets include ``object_type`` once more, at the end.

    The training's epoch is one pass over what it is given, so those samples come twice as
    often; the steps stay the same.
    """
    types = dataset.target_types()
    index = np.array(list(range(len(dataset))) +
                     [n for n in range(len(dataset)) if object_type in types[n]], dtype=np.intp)
    return Dataset(replace(dataset.metadata, size=int(index.size)),
                   scenes=tuple(dataset.scenes[i] for i in index),
                   **{name: array[index] for name, array in dataset.tensors().items()})


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("dataset", help="the run's training dataset (.gva)")
    parser.add_argument("--seed", type=int, required=True, help="the run's seed")
    parser.add_argument("--attempt", type=int, required=True, help="which start, from 1")
    parser.add_argument("--twice", default=None, help="an object type drawn twice per epoch")
    parser.add_argument("--steps", type=int, default=TrainConfig.steps)
    parser.add_argument("--out", required=True, help="checkpoint folder to write")
    args = parser.parse_args(argv)
    check = CheckConfig()
    data = load_dataset(args.dataset)
    kept, held = split_scenes(data, check.holdout, args.seed)
    if held is None:
        parser.error("the dataset is too small to hold anything out")
    if args.twice is not None:
        kept = drawn_twice(kept, args.twice)
    seed = attempt_seed(args.seed, args.attempt)
    model = new_model("kqv", data, seed=seed)
    model.fit(kept, TrainConfig(steps=args.steps, seed=seed, threads=1), progress=False)
    result = check_model(model, held, check.limit_cm, args.attempt, seed,
                         check.min_expected_success)
    print(result.headline())
    judged = judge_predictions(model.predict_samples(held, range(len(held))), held)
    if judged is not None:
        print("expected picked per object type: " + ", ".join(
            f"{name} {group.mean_probability:.3f} ({group.targets})"
            for name, group in judged.per_object.items()))
    model.save(args.out)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
