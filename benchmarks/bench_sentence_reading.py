"""Reading accuracy of sentence readings on phrasings never trained on (issue 37).

    python benchmarks/bench_sentence_reading.py [--seeds 5] [--out FILE] [--final]

(default ``benchmarks/results/sentence_reading.json``).

A reading names the target a sentence means; the trial then attends that target's Query. Each
candidate learns from the built-in text tasks' training phrasings alone (yumi scene) and reads:
the tasks' test phrasings (the fifth set, never trained on), the retired test phrasings
(``examples/phrases/retired-test-phrasings.tsv``), for types the new wordings
(``examples/phrases/new-wordings.tsv``), and the dev half of the wordings written outside the
project (``examples/phrases/outside-wordings-dev.tsv``, docs/phrase-sources.md); with
``--final``, once a reading was chosen, their test half too. Sides
(``selected-position-text``) and types (``selected-type-text``) are reported apart.
Candidates:

- ``prototype``: kqv's reading today: the nearest mean embedding of each target's training
  phrasings (cosine; no training, no seed).
- ``probe``: logistic regression on the pooled embedding (scikit-learn, ``C`` = 100).
- ``tokens``: :class:`perception.language.sentence_reading.TokenReader`, attention pooling over the
  frozen encoder's token embeddings and a linear head, trained per seed (0..N-1); each seed's
  count, their sum, and the worst seed.
- ``tokens+probe``: the sum of the two readers' probabilities (added after the first three
  were seen: the token reader reads sides best, the probe types).
- ``kqv``: the reading kqv adopted (``KqvConfig.sentence_reading = "auto"``), as a trained
  model has it: learnt from the distinct sentences its 20 training scenes draw (each seed its
  own draw, a sentence per scene and target, :func:`sim.tasks.queries.query_for`), the token
  reader for sides (reading only the words its training sentences had, issue 75) and the
  nearest prototype for types.

Also each reading's misses, so a reader sees which wordings fail.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import torch
from results_file import write_record
from sklearn.linear_model import LogisticRegression

from perception.interface import Condition, ConditionKind
from perception.language.sentence_reading import fit_token_reader, read_target
from perception.language.sentences import embed, token_embeddings, token_ids
from sim.tasks.queries import query_for
from sim.tasks.scene_specs import get_scene_spec
from sim.tasks.task_in_scene import condition_choices
from sim.tasks.task_spec import SIDES
from sim.tasks.task_toml import load_task, with_test_phrases

PHRASES = Path(__file__).resolve().parents[1] / "examples" / "phrases"
SETS = {"retired": PHRASES / "retired-test-phrasings.tsv",
        "new-wordings": PHRASES / "new-wordings.tsv",
        "outside-dev": PHRASES / "outside-wordings-dev.tsv"}
"""The held-out sets besides the tasks' own test phrasings, which chose among the readings."""
FINAL = {"outside-test": PHRASES / "outside-wordings-test.tsv"}
"""The outside wordings' test half: read only with ``--final``, once the reading was chosen
(docs/decisions/open-conditions.md), never to choose."""
TASKS = {"sides": "selected-position-text", "types": "selected-type-text"}
PROBE_C = 100.0
DEMOS = 20
"""Training scenes per task, as Table III's runs collect them."""
OUT = Path(__file__).resolve().parent / "results" / "sentence_reading.json"

Pairs = list[tuple[str, int]]


def phrase_sets(task_name: str, final: bool = False
                ) -> tuple[tuple[str, ...], Pairs, dict[str, Pairs]]:
    """The task's targets, its training phrasings and each held-out set, as (phrase, target).

    With ``final``, the outside wordings' test half too.
    """
    spec = get_scene_spec("yumi")
    task = load_task(task_name)
    targets = condition_choices(task, spec)
    assert task.phrasings is not None

    def pairs(table: Any, split: str) -> Pairs:
        return [(p, k) for k, t in enumerate(targets) for p in table.of(split, t)]

    held_out = {"fifth": pairs(task.phrasings, "test")}
    for name, path in (SETS | FINAL if final else SETS).items():
        phrasings = with_test_phrases(task, path, targets, spec.object_types + SIDES).phrasings
        found = pairs(phrasings, "test")
        if found and not (name == "new-wordings" and task_name == TASKS["sides"]):
            held_out[name] = found
    return targets, pairs(task.phrasings, "train"), held_out


def prototype_reader(train: Pairs, targets: int) -> Callable[[str], int]:
    vectors, named = np.stack([embed(p) for p, _ in train]), np.array([k for _, k in train])
    prototypes = np.stack([vectors[named == k].mean(axis=0) for k in range(targets)])
    return lambda sentence: int(np.argmax(prototypes @ embed(sentence)))


def fitted_probe(train: Pairs) -> LogisticRegression:
    probe = LogisticRegression(C=PROBE_C, fit_intercept=False, max_iter=5000)
    return probe.fit(np.stack([embed(p) for p, _ in train]), [k for _, k in train])


def probe_reader(probe: LogisticRegression) -> Callable[[str], int]:
    return lambda sentence: int(probe.predict(embed(sentence)[None])[0])


def token_reader(train: Pairs, targets: int, seed: int, probe: LogisticRegression | None = None,
                 seen_words: bool = False) -> Callable[[str], int]:
    """The token reader of ``seed``; with ``probe``, their probabilities summed.

    With ``seen_words`` it reads only the words its training sentences had, as kqv's does.
    """
    ids = token_ids if seen_words else None
    reader = fit_token_reader(train, targets, token_embeddings, seed, ids=ids)
    if probe is None:
        return lambda sentence: read_target(reader, token_embeddings(sentence),
                                            token_ids(sentence) if seen_words else None)

    def both(sentence: str) -> int:
        with torch.no_grad():
            logits = reader(torch.as_tensor(np.array(token_embeddings(sentence))))
        p_tokens = torch.softmax(logits, dim=0).numpy()
        return int(np.argmax(p_tokens + probe.predict_proba(embed(sentence)[None])[0]))

    return both


def drawn(task_name: str, seed: int, scenes: int = DEMOS) -> Pairs:
    """The distinct training (phrase, target) pairs ``scenes`` training scenes of ``seed`` draw."""
    task, spec = load_task(task_name), get_scene_spec("yumi")
    choices = condition_choices(task, spec)
    kind = ConditionKind.SIDE if set(choices) <= set(SIDES) else ConditionKind.OBJECT_TYPE
    pairs = set()
    for index in range(scenes):
        for k, choice in enumerate(choices):
            query = query_for(task, "yumi", Condition(kind, choice, choices), seed, 0, index)
            assert query is not None and query.value is not None
            pairs.add((query.value, k))
    return sorted(pairs)


def kqv_reader(kind: str, task_name: str, targets: int, seed: int) -> Callable[[str], int]:
    """The ``"auto"`` reading of kqv as trained on the sentences of seed ``seed``'s scenes."""
    train = drawn(task_name, seed)
    if kind == "types":
        return prototype_reader(train, targets)
    return token_reader(train, targets, seed, seen_words=True)


def score(read: Callable[[str], int], sets: dict[str, Pairs], targets: tuple[str, ...]
          ) -> dict[str, Any]:
    """Per held-out set: right of all, and the misses (phrase, named, read)."""
    out: dict[str, Any] = {}
    for name, pairs in sets.items():
        misses = [(p, targets[k], targets[read(p)]) for p, k in pairs if read(p) != k]
        out[name] = {"right": len(pairs) - len(misses), "of": len(pairs),
                     "misses": [list(m) for m in misses]}
    return out


def seeded(per_seed: list[dict[str, Any]], held_out: dict[str, Pairs]) -> dict[str, Any]:
    """Seeds' scores of one candidate: each seed's right, their sum, the worst, the misses."""
    return {name: {"right_per_seed": [s[name]["right"] for s in per_seed],
                   "right": sum(s[name]["right"] for s in per_seed),
                   "of": len(per_seed) * len(held_out[name]),
                   "worst_seed_right": min(s[name]["right"] for s in per_seed),
                   "misses": sorted({tuple(m) for s in per_seed for m in s[name]["misses"]})}
            for name in held_out}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seeds", type=int, default=5, help="token readers trained (5)")
    parser.add_argument("--out", type=Path, default=OUT)
    parser.add_argument("--final", action="store_true",
                        help="also read the outside wordings' test half (once a reading is chosen)")
    args = parser.parse_args()
    record: dict[str, Any] = {"seeds": args.seeds, "final": args.final}
    for kind, task_name in TASKS.items():
        targets, train, held_out = phrase_sets(task_name, args.final)
        rows: dict[str, Any] = {"training_phrasings": len(train)}
        rows["prototype"] = score(prototype_reader(train, len(targets)), held_out, targets)
        probe = fitted_probe(train)
        rows["probe"] = score(probe_reader(probe), held_out, targets)
        for candidate, helper in (("tokens", None), ("tokens+probe", probe)):
            per_seed, fit_s = [], []
            for seed in range(args.seeds):
                started = time.perf_counter()
                read = token_reader(train, len(targets), seed, helper)
                fit_s.append(time.perf_counter() - started)
                per_seed.append(score(read, held_out, targets))
            rows[candidate] = seeded(per_seed, held_out)
            rows[candidate]["fit_seconds_median"] = float(np.median(fit_s))
        per_seed = [score(kqv_reader(kind, task_name, len(targets), seed), held_out, targets)
                    for seed in range(args.seeds)]
        rows["kqv"] = seeded(per_seed, held_out)
        rows["kqv"]["training_phrasings_per_seed"] = [len(drawn(task_name, seed))
                                                      for seed in range(args.seeds)]
        record[kind] = rows
        for candidate in ("prototype", "probe", "tokens", "tokens+probe", "kqv"):
            cells = [f"{name} {rows[candidate][name]['right']}/{rows[candidate][name]['of']}"
                     for name in held_out]
            print(f"{kind:5s} {candidate:12s} " + ", ".join(cells))
    write_record(args.out, record, default=list)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
