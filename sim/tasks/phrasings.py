"""Phrasings of a text condition: the sentences that name each target, split into train and test.

A text task (``[condition] given_as = "text"``) names its target in a sentence drawn from a
list per target ("the red mug", "the thing you drink coffee from"). The list is split like the
scenes: training scenes draw from ``train``, test scenes and trials from ``test``, and the two
never share a phrasing, so a trial measures how a model reads words it was not trained on.
``gva trials --phrases FILE`` replaces the test phrasings with a user's own: one
``phrase<TAB>target`` per line, where target is an object type or a side.
"""

from __future__ import annotations

import unicodedata
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from perception.interface import MAX_SENTENCE_CHARS
from sim.errors import InvalidInputError

MAX_PHRASINGS = 100
"""Phrasings per target and split: a list for people to write, not a corpus."""
MAX_PHRASE_FILE_BYTES = 256 * 1024
"""A phrase file is a few hundred lines; a bigger file is refused unread."""

Table = tuple[tuple[str, tuple[str, ...]], ...]
"""Target -> its phrasings, as sorted pairs (hashable, for a frozen task)."""


def normalised(phrase: str) -> str:
    """The form two phrasings are compared in: NFKC, lower case, single spaces."""
    return " ".join(unicodedata.normalize("NFKC", phrase).lower().split())


@dataclass(frozen=True)
class Phrasings:
    """Each target's phrasings for training scenes and for test scenes (and trials).

    Args:
        train: Target -> phrasings the training scenes draw from.
        test: Target -> phrasings the test scenes and trials draw from; none is in ``train``.
        source: Where they came from, for messages.

    """

    train: Table
    test: Table
    source: str = field(default="<code>", compare=False)

    def __post_init__(self) -> None:
        for split in ("train", "test"):
            object.__setattr__(self, split, _table(f"{self.source}: condition.phrases.{split}",
                                                   getattr(self, split)))
        seen = {normalised(p): target for target, phrases in self.train for p in phrases}
        for target, phrases in self.test:
            for phrase in phrases:
                if normalised(phrase) in seen:
                    raise InvalidInputError(
                        f"{self.source}: condition.phrases.test.{target}", phrase,
                        f"a phrasing not in condition.phrases.train (it is under "
                        f"{seen[normalised(phrase)]!r}): test words must be unseen in training")

    def of(self, split: str, target: str) -> tuple[str, ...]:
        """The phrasings of ``target`` in ``split`` (``"train"`` or ``"test"``); () if none."""
        return dict(getattr(self, split)).get(target, ())

    def check_targets(self, targets: Iterable[str], where: str) -> None:
        """An error unless every target in ``targets`` has phrasings in both splits."""
        for split in ("train", "test"):
            missing = [t for t in targets if not self.of(split, t)]
            if missing:
                raise InvalidInputError(
                    f"{where}: condition.phrases.{split}", f"no phrasings for {missing}",
                    f"at least one phrasing for every target the task can name "
                    f"({', '.join(targets)})")

    def with_test(self, test: Table, source: str) -> Phrasings:
        """The same training phrasings, tested with ``test`` (a user's phrase file)."""
        return Phrasings(self.train, test, f"{self.source}, test phrasings from {source}")

    def to_json(self) -> dict[str, dict[str, list[str]]]:
        """The phrasings as TOML/JSON-able tables."""
        return {split: {t: list(p) for t, p in getattr(self, split)} for split in ("train", "test")}


def _table(where: str, table: Any) -> Table:
    """``table`` (a mapping or pairs of target -> phrasings) checked, as sorted pairs."""
    pairs = table.items() if isinstance(table, Mapping) else table
    try:
        pairs = list(pairs)
    except TypeError:
        raise InvalidInputError(where, type(table).__name__,
                                "a table of target = [phrasings]") from None
    checked = []
    for pair in pairs:
        if not (isinstance(pair, tuple | list) and len(pair) == 2):
            raise InvalidInputError(where, pair, "target = [phrasings]")
        target, phrases = pair
        if not isinstance(target, str) or not target:
            raise InvalidInputError(where, target, "a target name (an object type or a side)")
        if isinstance(phrases, str) or not isinstance(phrases, list | tuple) or not phrases \
                or len(phrases) > MAX_PHRASINGS:
            raise InvalidInputError(f"{where}.{target}", phrases,
                                    f"a list of 1-{MAX_PHRASINGS} phrasings")
        for phrase in phrases:
            if not (isinstance(phrase, str) and phrase.strip() and len(phrase) <=
                    MAX_SENTENCE_CHARS and phrase.isprintable()):
                raise InvalidInputError(f"{where}.{target}", phrase,
                                        f"1-{MAX_SENTENCE_CHARS} printable characters")
        if len({normalised(p) for p in phrases}) != len(phrases):
            raise InvalidInputError(f"{where}.{target}", phrases, "distinct phrasings")
        checked.append((target, tuple(phrases)))
    if len({t for t, _ in checked}) != len(checked):
        raise InvalidInputError(where, [t for t, _ in checked], "each target once")
    return tuple(sorted(checked))


def read_phrase_file(path: str | Path, targets: Iterable[str]) -> Table:
    """A user's phrase file: lines ``phrase<TAB>target``; ``#`` comments and blank lines skip.

    Every target must be one of ``targets`` (the scene's object types and sides); a target the
    task does not name is kept, and the task's own check says which it can use.

    Raises:
        InvalidInputError: The file is missing, too big, not UTF-8, or a line is malformed;
            the message names the line.

    """
    file = Path(path)
    if not file.is_file():
        raise InvalidInputError("phrases", str(path), "an existing text file")
    data = file.read_bytes()[:MAX_PHRASE_FILE_BYTES + 1]
    if len(data) > MAX_PHRASE_FILE_BYTES:
        raise InvalidInputError("phrases", str(path), f"a file of at most "
                                f"{MAX_PHRASE_FILE_BYTES} bytes")
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise InvalidInputError("phrases", str(path), "UTF-8 text") from None
    allowed = tuple(targets)
    table: dict[str, list[str]] = {}
    for number, line in enumerate(text.splitlines(), start=1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        parts = line.split("\t")
        where = f"phrases {file.name} line {number}"
        if len(parts) != 2:
            raise InvalidInputError(where, line, "phrase<TAB>target (one tab)")
        phrase, target = parts[0].strip(), parts[1].strip()
        if target not in allowed:
            raise InvalidInputError(where, target, f"one of {', '.join(allowed)}")
        table.setdefault(target, []).append(phrase)
    if not table:
        raise InvalidInputError("phrases", str(path), "at least one phrase<TAB>target line")
    return _table(f"phrases {file.name}", table)
