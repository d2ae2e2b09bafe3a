"""How well the frozen sentence encoder alone tells a text task's test phrasings apart.

    python studies/check_sentence_prototypes.py [--out FILE]

(default ``benchmarks/results/sentence_prototypes.json``).

For each built-in text task and scene, and for the example phrase file of new wordings: each
target's prototype is the mean embedding of its training phrasings; a test phrasing is named
right when its own target's prototype is the nearest (cosine). No image, no training: what a
Query could at best read from the words, and where the encoder itself confuses them (sides).

It lists the training phrasings nearer another target's prototype than their own (themselves
included): under kqv's nearest reading each trains that target's Query on the wrong object.
It also chooses kqv's ``sentence_temperature`` from the training phrasings alone: each one in
turn is left out of its target's prototype and read as kqv reads a sentence (softmax of its
cosines over the temperature); the temperature whose mean weight on the right target is
highest wins. No test phrasing takes part in that choice.

It also sets the prototypes' nearest mean beside a linear probe (logistic regression on the
embedding, scikit-learn, no intercept, ``C`` = 100), two ways: each training phrasing left out
in turn, and the retired test phrasings read against all the training ones. The first favours
the probe wherever phrasings come in pairs that differ by one word ("the object on the
left"/"... right"): a left-out phrasing's twin stays in the other target's prototype only.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

import numpy as np
from results_file import add_out_option, write_record
from sklearn.linear_model import LogisticRegression

from perception.language.sentences import embed
from sim.tasks.scene_specs import get_scene_spec
from sim.tasks.task_in_scene import condition_choices
from sim.tasks.task_spec import SIDES
from sim.tasks.task_toml import load_task, with_test_phrases

PHRASES = Path(__file__).resolve().parents[1] / "examples" / "phrases"
NEW_WORDINGS = PHRASES / "new-wordings.tsv"
RETIRED = PHRASES / "retired-test-phrasings.tsv"
PROBE_C = 100.0  # the linear probe's inverse L2 strength


def prototype_scores(task_name: str, scene: str, phrases: Path | None = None) -> dict:
    """Each test phrasing's cosine to every target's training prototype, and the verdict."""
    spec = get_scene_spec(scene)
    task = load_task(task_name)
    targets = condition_choices(task, spec)
    if phrases is not None:
        task = with_test_phrases(task, phrases, targets, spec.object_types + SIDES)
    assert task.phrasings is not None
    prototypes = {t: np.mean([embed(p) for p in task.phrasings.of("train", t)], axis=0)
                  for t in targets}
    rows: list[dict[str, Any]] = []
    for target in targets:
        for phrase in task.phrasings.of("test", target):
            cosine = {t: float(embed(phrase) @ v / np.linalg.norm(v))
                      for t, v in prototypes.items()}
            rows.append({"phrase": phrase, "target": target, "cosine": cosine,
                         "nearest": max(cosine, key=cosine.__getitem__)})
    right = sum(r["nearest"] == r["target"] for r in rows)
    return {"task": task_name, "scene": scene,
            "phrases": phrases.name if phrases else "the task's test", "named_right": right,
            "phrasings": len(rows), "rows": rows}


TEMPERATURES = (0.01, 0.02, 0.05, 0.1, 0.2)


def leave_one_out(task_name: str, scene: str) -> dict:
    """Each training phrasing read against the prototypes: left out of its own, and left in.

    Left out: the mean softmax weight on its own target, per temperature. Left in: the
    phrasings nearest another target's prototype all the same. (A model's prototypes come from
    the phrasings its dataset drew, so a seed may misread others.)
    """
    spec = get_scene_spec(scene)
    task = load_task(task_name)
    assert task.phrasings is not None
    targets = condition_choices(task, spec)
    rows = [(embed(p), k, p) for k, t in enumerate(targets) for p in task.phrasings.of("train", t)]

    def cosines(vector: np.ndarray, left_out: int | None) -> np.ndarray:
        means = [np.mean([r for m, (r, k, _) in enumerate(rows) if k == target and m != left_out],
                         axis=0) for target in range(len(targets))]
        return np.array([vector @ v / np.linalg.norm(v) for v in means])

    left_out = np.stack([cosines(vector, n) for n, (vector, _, _) in enumerate(rows)])  # (n, k)
    left_out -= left_out.max(axis=1, keepdims=True)
    own = np.array([k for _, k, _ in rows])
    weights: dict[str, float] = {}
    for temperature in TEMPERATURES:
        soft = np.exp(left_out / temperature)  # (n, k)
        weights[str(temperature)] = float(np.mean(soft[np.arange(len(rows)), own] /
                                                  soft.sum(axis=1)))
    misread = [phrase for vector, own, phrase in rows
               if int(np.argmax(cosines(vector, None))) != own]
    return {"task": task_name, "scene": scene, "phrasings": len(rows),
            "read_as_another_target": misread, "mean_weight_on_own_target": weights,
            "best_temperature": float(max(weights, key=weights.__getitem__)),
            "left_out_named_right": int((left_out.argmax(axis=1) == own).sum())}


def probe_scores(task_name: str, scene: str) -> dict:
    """How many phrasings the linear probe names right: training ones left out, retired ones.

    The prototypes' counts of the same are in :func:`leave_one_out` and :func:`prototype_scores`
    (with the retired file).
    """
    spec = get_scene_spec(scene)
    task = load_task(task_name)
    assert task.phrasings is not None
    targets = condition_choices(task, spec)
    own = np.array([k for k, t in enumerate(targets) for _ in task.phrasings.of("train", t)])
    vectors = np.stack([embed(p) for t in targets for p in task.phrasings.of("train", t)])

    def fitted(keep: np.ndarray) -> LogisticRegression:
        return LogisticRegression(C=PROBE_C, fit_intercept=False, max_iter=5000).fit(
            vectors[keep], own[keep])

    left_out = sum(int(fitted(np.arange(len(own)) != n).predict(vectors[n:n + 1])[0] == own[n])
                   for n in range(len(own)))
    retired = with_test_phrases(task, RETIRED, targets, spec.object_types + SIDES).phrasings
    assert retired is not None
    pairs = [(embed(p), k) for k, t in enumerate(targets) for p in retired.of("test", t)]
    read = fitted(np.ones(len(own), dtype=bool)).predict(np.stack([v for v, _ in pairs]))
    return {"task": task_name, "scene": scene, "training_phrasings": len(own),
            "left_out_named_right": left_out, "retired_phrasings": len(pairs),
            "retired_named_right": int((read == np.array([k for _, k in pairs])).sum())}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_out_option(parser, "sentence_prototypes")
    args = parser.parse_args()
    results = [prototype_scores("selected-type-text", "yumi"),
               prototype_scores("selected-type-text", "paper-sim"),
               prototype_scores("selected-position-text", "yumi"),
               prototype_scores("selected-type-text", "yumi", NEW_WORDINGS),
               prototype_scores("selected-position-text", "yumi", NEW_WORDINGS),
               prototype_scores("selected-type-text", "yumi", RETIRED),
               prototype_scores("selected-position-text", "yumi", RETIRED)]
    for result in results:
        print(f"{result['task']} / {result['scene']} ({result['phrases']}): "
              f"{result['named_right']} of {result['phrasings']} test phrasings nearest their "
              "own target's prototype")
    choices = [leave_one_out(task, scene) for task, scene in
               (("selected-type-text", "yumi"), ("selected-type-text", "paper-sim"),
                ("selected-position-text", "yumi"))]
    for choice in choices:
        print(f"{choice['task']} / {choice['scene']}: training phrasings read as another "
              f"target: {choice['read_as_another_target'] or 'none'}")
        print(f"{choice['task']} / {choice['scene']}: training phrasings left out, weight on "
              "their own target by temperature " + ", ".join(
                  f"{t}: {w:.3f}" for t, w in choice["mean_weight_on_own_target"].items())
              + f"; named right: {choice['left_out_named_right']} of {choice['phrasings']}")
    probes = [probe_scores(task, "yumi")
              for task in ("selected-type-text", "selected-position-text")]
    for scores in probes:
        print(f"{scores['task']} / {scores['scene']}: the linear probe names right "
              f"{scores['left_out_named_right']} of {scores['training_phrasings']} training "
              f"phrasings left out, {scores['retired_named_right']} of "
              f"{scores['retired_phrasings']} retired test phrasings")
    write_record(args.out, {"nearest_prototype": results, "temperature_leave_one_out": choices,
                            "linear_probe": probes})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
