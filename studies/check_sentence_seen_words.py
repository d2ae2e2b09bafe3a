"""Study (issue 75): the side reader reading every word, or only the words its training had.

kqv's side reader (:class:`perception.language.sentence_reading.TokenReader`) read "the
right-side object please" as left at seeds 20 and 21 of the text bar run: four picks lost at
each. Unseen word pieces ("-", "side", "please") have embeddings its attention query never
learned to score. This trains, per seed, the reader kqv's 20 training scenes of
``selected-position-text`` would train (the distinct sentences they draw,
``bench_sentence_reading.drawn``), and counts the misreadings of each held-out set of side
phrasings, read two ways: every word (the reader before issue 75) and only the word pieces its
training sentences had. The choice is made on the retired and outside (dev) sets; the fifth
set holds the phrasing that failed, shown apart. ``--kind types`` reads the type phrasings
the same way (kqv reads types by prototypes, not by this reader).

Usage:
    python studies/check_sentence_seen_words.py [--seeds 30] [--kind sides|types]

Answered in docs/decisions/open-conditions.md ("Only the words it saw").
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

from bench_sentence_reading import TASKS, drawn, phrase_sets

from perception.language.sentence_reading import fit_token_reader, read_target
from perception.language.sentences import token_embeddings, token_ids


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seeds", type=int, default=30, help="seeds 0..N-1 (30)")
    parser.add_argument("--kind", choices=tuple(TASKS), default="sides")
    args = parser.parse_args()
    targets, _, held_out = phrase_sets(TASKS[args.kind])
    misses = {name: {"every word": 0, "seen words": 0} for name in held_out}
    failing: dict[str, int] = {}
    for seed in range(args.seeds):
        pairs = drawn(TASKS[args.kind], seed)
        reader = fit_token_reader(pairs, len(targets), token_embeddings, seed, ids=token_ids)
        for name, phrasings in held_out.items():
            for phrase, named in phrasings:
                words = token_embeddings(phrase)
                misses[name]["every word"] += read_target(reader, words) != named
                if read_target(reader, words, token_ids(phrase)) != named:
                    misses[name]["seen words"] += 1
                    failing[phrase] = failing.get(phrase, 0) + 1
        print(f"seed {seed}: " + ", ".join(f"{n} {m['every word']}/{m['seen words']}"
                                            for n, m in misses.items()), flush=True)
    print(f"misread over seeds 0-{args.seeds - 1} (every word / seen words):")
    for name, phrasings in held_out.items():
        print(f"  {name}: {misses[name]['every word']} / {misses[name]['seen words']} "
              f"of {len(phrasings) * args.seeds}")
    print("still misread with seen words (phrase: seeds):")
    for phrase, count in sorted(failing.items(), key=lambda item: -item[1]):
        print(f"  {phrase!r}: {count}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
