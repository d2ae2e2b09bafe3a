"""Which target a sentence names, read from its words (issue 37): attention over the tokens.

kqv reads a sentence by its pooled embedding's cosines to each target's training prototype.
The pooled vector averages a side's one telling word away: all-MiniLM-L6-v2 puts "the one on
the right" as near the left prototype as the right one (cosines 0.7375 and 0.7368), so a third
of the "right" phrasings never trained on read as left. A :class:`TokenReader` reads the frozen
encoder's token embeddings instead: a learned query scores each token, the softmax of the
scores pools them, and a linear layer gives one logit per target. It trains on the training
phrasings alone (what each names), in seconds on one core; the encoder stays frozen, and no
keyword is written by hand. Its measurements against the prototypes and a linear probe:
``benchmarks/bench_sentence_reading.py`` and docs/decisions/open-conditions.md.

It reads only the words its training sentences had (issue 75). A word it never saw has an
embedding its query never learned to score, and in "the right-side object please" the unseen
"-", "side" and "please" drew the attention off "right" at some seeds (the sentence read as
left, four picks lost at each). Which word pieces it saw is kept with its weights; a sentence
with none of them is read whole.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import torch

from perception.errors import InvalidInputError
from perception.language.sentences import (
    EMBEDDING_SIZE,
    VOCABULARY_SIZE,
    token_embeddings,
    token_ids,
)


@dataclass(frozen=True)
class TokenReaderConfig:
    """How a :class:`TokenReader` trains.

    Args:
        epochs: Passes over the training phrasings, one phrasing a step, shuffled per pass.
        learning_rate: Adam's step size.
        weight_decay: Adam's L2 weight decay: a few dozen phrasings, so keep the head small.

    """

    epochs: int = 60
    learning_rate: float = 1e-2
    weight_decay: float = 1e-3

    def __post_init__(self) -> None:
        if isinstance(self.epochs, bool) or not isinstance(self.epochs, int) or self.epochs < 1:
            raise InvalidInputError("epochs", self.epochs, "an integer >= 1")
        for name in ("learning_rate", "weight_decay"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0) or (name == "learning_rate"
                                                                 and value == 0.0):
                raise InvalidInputError(name, value, "a finite number > 0" if name ==
                                        "learning_rate" else "a finite number >= 0")


class TokenReader(torch.nn.Module):
    """Attention pooling over a sentence's token embeddings, then one logit per target.

    Args:
        targets: How many targets a sentence may name.
        width: The token embeddings' width.
        vocabulary: How many word-piece ids the tokenizer has: the size of :attr:`seen`.

    """

    seen: torch.Tensor
    """(vocabulary,) uint8: 1 for each word piece the training sentences had (set by
    :func:`fit_token_reader`); all ones reads every word (a checkpoint from before it)."""

    def __init__(self, targets: int, width: int = EMBEDDING_SIZE,
                 vocabulary: int = VOCABULARY_SIZE) -> None:
        super().__init__()
        if isinstance(targets, bool) or not isinstance(targets, int) or targets < 2:
            raise InvalidInputError("targets", targets, "an integer >= 2")
        self.query = torch.nn.Parameter(torch.zeros(width))  # all tokens alike at the start
        self.head = torch.nn.Linear(width, targets)
        self.register_buffer("seen", torch.ones(vocabulary, dtype=torch.uint8))

    def known(self, tokens: torch.Tensor, ids: np.ndarray | None) -> torch.Tensor:
        """The rows of ``tokens`` (n, width) whose word pieces ``ids`` (n,) training saw.

        All of them where ``ids`` is None or none was seen: a sentence is never read as
        nothing.
        """
        if ids is None:
            return tokens
        ids = np.array(ids, dtype=np.int64)  # a copy: the encoder's cached ids are read-only
        if ids.shape != (tokens.shape[0],) or ids.min(initial=0) < 0 or \
                ids.max(initial=0) >= self.seen.shape[0]:
            raise InvalidInputError("token ids", ids.shape, f"one id in [0, "
                                    f"{self.seen.shape[0]}) per token ({tokens.shape[0]})")
        kept = self.seen[torch.as_tensor(ids, dtype=torch.long)].bool()
        return tokens[kept] if bool(kept.any()) else tokens

    def attention(self, tokens: torch.Tensor) -> torch.Tensor:
        """Each token's weight (n,) in the pooled vector of ``tokens`` (n, width)."""
        return torch.softmax(tokens @ self.query, dim=0)

    def forward(self, tokens: torch.Tensor) -> torch.Tensor:
        """The targets' logits (targets,) for one sentence's ``tokens`` (n, width)."""
        return self.head(self.attention(tokens) @ tokens)


def fit_token_reader(
    phrasings: Sequence[tuple[str, int]], targets: int, tokens: Callable[[str], np.ndarray],
    seed: int, config: TokenReaderConfig | None = None,
    ids: Callable[[str], np.ndarray] | None = None,
) -> TokenReader:
    """A :class:`TokenReader` trained on ``phrasings``: (sentence, the target it names) pairs.

    ``tokens`` gives a sentence's token embeddings (n, width) from the frozen encoder, ``ids``
    its word pieces' ids (n,): the reader keeps which it saw and reads only those (None: it
    reads every word). Cross-entropy, Adam, one phrasing a step; ``seed`` sets the start and
    the order.

    Raises:
        InvalidInputError: No phrasings, a target outside ``[0, targets)``, or one target that
            no phrasing names.

    """
    config = config or TokenReaderConfig()
    if not phrasings:
        raise InvalidInputError("phrasings", "none", "at least one phrasing per target")
    named = sorted({k for _, k in phrasings})
    if named != list(range(targets)):
        raise InvalidInputError("phrasings' targets", named, f"every target 0..{targets - 1}")
    data = [(torch.as_tensor(np.array(tokens(sentence), dtype=np.float32)), torch.tensor([k]))
            for sentence, k in phrasings]
    generator = torch.Generator().manual_seed(seed)
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(seed)
        reader = TokenReader(targets, data[0][0].shape[1])
    if ids is not None:
        seen = np.concatenate([np.asarray(ids(sentence)) for sentence, _ in phrasings])
        reader.seen.zero_()
        reader.seen[torch.as_tensor(seen, dtype=torch.long)] = 1
    optimiser = torch.optim.Adam(reader.parameters(), lr=config.learning_rate,
                                 weight_decay=config.weight_decay)
    for _ in range(config.epochs):
        for i in torch.randperm(len(data), generator=generator).tolist():
            sentence_tokens, target = data[i]
            loss = torch.nn.functional.cross_entropy(reader(sentence_tokens)[None], target)
            optimiser.zero_grad()
            loss.backward()
            optimiser.step()
    reader.eval()
    return reader


def read_target(reader: TokenReader, sentence_tokens: np.ndarray,
                sentence_ids: np.ndarray | None = None) -> int:
    """The target ``reader`` reads a sentence as naming.

    From its token embeddings (n, width) and, where given, its word pieces' ids (n,): then
    only the words training saw are read.
    """
    tokens = torch.as_tensor(np.array(sentence_tokens, dtype=np.float32))
    with torch.no_grad():
        return int(torch.argmax(reader(reader.known(tokens, sentence_ids))))


def fit_sentence_reader(named: Sequence[tuple[str, str]], choices: Sequence[str], seed: int
                        ) -> TokenReader:
    """A reader of ``named``'s distinct (sentence, target name) pairs by the shared encoder.

    What a model trains at its first fit: seconds on one core, the encoder frozen, no word
    written by hand; it keeps the word pieces it saw.
    """
    phrasings = sorted({(sentence, list(choices).index(name)) for sentence, name in named})
    return fit_token_reader(phrasings, len(choices), token_embeddings, seed, ids=token_ids)


def read_sentences(reader: TokenReader, sentences: Sequence[str]) -> list[int]:
    """The target ``reader`` reads each sentence as naming, by the shared encoder's tokens."""
    return [read_target(reader, token_embeddings(s), token_ids(s)) for s in sentences]
