"""The token reader: it learns which word names the target, and reads new wordings by it."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from perception.errors import InvalidInputError
from perception.sentence_reading import (
    TokenReader,
    TokenReaderConfig,
    fit_token_reader,
    read_target,
)

WIDTH = 32
_RNG = np.random.default_rng(37)
WORDS = {word: _RNG.normal(size=WIDTH) for word in (
    "left right the one on side of table item pick up thing please grab that object "
    "near far at over there hand me").split()}
# The side word is 1 of 4-9 tokens; the fillers differ between the training and new wordings.
TRAIN = [("the one on the left", 0), ("the one on the right", 1), ("pick up the left item", 0),
         ("pick up the right item", 1), ("grab the thing on the left side", 0),
         ("grab the thing on the right side", 1), ("the left object please", 0),
         ("the right object please", 1)]
NEW = [("hand me that left one", 0), ("over there on the right of the table", 1),
       ("the item at the left side of the table", 0), ("that right thing there", 1)]


def tokens(sentence: str) -> np.ndarray:
    """Made-up token embeddings: one fixed vector per word, a little noise per use."""
    noise = np.random.default_rng(len(sentence)).normal(scale=0.05, size=(1, WIDTH))
    return np.stack([WORDS[w] for w in sentence.split()]) + noise


def test_the_reader_reads_new_wordings_by_their_side_word():
    reader = fit_token_reader(TRAIN, 2, tokens, seed=0)
    assert [read_target(reader, tokens(s)) for s, _ in NEW] == [k for _, k in NEW]
    for sentence, _ in NEW:  # the side word gets the most attention
        weights = reader.attention(torch.as_tensor(tokens(sentence), dtype=torch.float32))
        side = [i for i, w in enumerate(sentence.split()) if w in ("left", "right")]
        assert int(weights.argmax()) in side


def test_training_is_seeded():
    first = fit_token_reader(TRAIN, 2, tokens, seed=3, config=TokenReaderConfig(epochs=5))
    again = fit_token_reader(TRAIN, 2, tokens, seed=3, config=TokenReaderConfig(epochs=5))
    for a, b in zip(first.parameters(), again.parameters(), strict=True):
        assert bool((a == b).all())


def test_bad_input_is_named():
    with pytest.raises(InvalidInputError, match=r"targets = 1 is not allowed: an integer >= 2"):
        TokenReader(1)
    with pytest.raises(InvalidInputError, match=r"phrasings' targets = \[0\] is not allowed: "
                                                r"every target 0\.\.1"):
        fit_token_reader([("the left one", 0)], 2, tokens, seed=0)
    with pytest.raises(InvalidInputError, match=r"epochs = 0 is not allowed"):
        TokenReaderConfig(epochs=0)
    with pytest.raises(InvalidInputError, match=r"learning_rate = 0\.0 is not allowed: a "
                                                r"finite number > 0"):
        TokenReaderConfig(learning_rate=0.0)
