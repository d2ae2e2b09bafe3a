"""The training samples as a kqv model trains on them: sentences by what they name, mirrored.

The choices :meth:`KqvModel.fit <perception.models.kqv.KqvModel.fit>` makes of a dataset before
its training loop (and the sentence reader it trains of the dataset's sentences), apart from the
model so each reads on its own.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from torch import Tensor

from perception.interface import ConditionKind
from perception.language.sentence_reading import TokenReader, fit_sentence_reader
from perception.learning.data import Dataset
from perception.learning.learnable import ModelSpec
from perception.learning.mirror import MIRROR_FLAG, Mirror
from perception.learning.torch_pieces import unit


def named_dataset(dataset: Dataset, prototypes: Tensor | None) -> Dataset:
    """The dataset as the Queries train on it: each sentence replaced by what it names.

    A model that reads a sentence by prototypes gives it the Query of the target it reads
    as. A training sentence that reads as another target (MiniLM puts "left" and "right"
    close) would then train that target's Query on this one's object, half a table away.
    The scene records say what each sentence names, so each training sentence becomes its
    named target's prototype (at unit length), which reads as that target: every target's
    Query trains on exactly the scenes that name it. Other datasets (``prototypes`` None) are
    returned as given.
    """
    if prototypes is None:
        return dataset
    rows = prototypes.numpy()  # (k, C); zeros for a choice no sample names (none is asked)
    units = rows / np.maximum(np.linalg.norm(rows, axis=1, keepdims=True), 1e-12)
    choices = dataset.metadata.condition_choices
    named = [choices.index(name) for name in dataset.condition_names()]
    return replace(dataset, conditions=units[named].astype(np.float32))


def mirror_for(spec: ModelSpec, mirror: bool | None, dataset: Dataset,
               prototypes: Tensor | None, seed: int) -> Mirror | None:
    """The mirror ``KqvConfig.mirror`` asks for (None: where the dataset allows it).

    A sentence task mirrors only where each sentence trains as its named target's row (the
    prototype readings): the mirrored sample gets the other side's row. One that reads the
    embedding itself cannot say which side a sentence names, so it is not mirrored.
    """
    rows = None if prototypes is None else unit(prototypes, dim=-1).numpy()
    if mirror is None:
        mirror = dataset.metadata.extra.get(MIRROR_FLAG) is True and (
            spec.condition_kind is not ConditionKind.TEXT or rows is not None)
    return Mirror(spec, seed, rows if spec.condition_kind is ConditionKind.TEXT else None) \
        if mirror else None


def sentence_reader(dataset: Dataset, spec: ModelSpec, seed: int) -> TokenReader:
    """A :class:`TokenReader` of ``dataset``'s sentences and the targets they name."""
    named = [(dataset.condition(i).value or "", name)
             for i, name in enumerate(dataset.condition_names()) if name is not None]
    return fit_sentence_reader(named, spec.condition_choices, seed)
