"""The token reader: it learns which word names the target, and reads new wordings by it."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
import torch
from user_models import CAMERA, TYPES, given_as, synthetic_dataset

from perception.errors import InvalidInputError
from perception.interface import Condition, ConditionKind
from perception.language.sentence_reading import (
    TokenReader,
    TokenReaderConfig,
    fit_token_reader,
    read_target,
)
from perception.language.sentences import EMBEDDING_SIZE
from perception.learning.checkpoint import save_checkpoint
from perception.learning.data import Dataset
from perception.learning.learnable import ModelSpec
from perception.learning.mirror import MIRROR_FLAG
from perception.learning.train import TrainConfig
from perception.models.kqv import KqvConfig, KqvModel
from perception.models.kqv_net import KqvNet, sentence_reading

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


def ids(sentence: str) -> np.ndarray:
    """Made-up word-piece ids: each word's place in :data:`WORDS`."""
    return np.array([list(WORDS).index(w) for w in sentence.split()])


def test_the_reader_reads_new_wordings_by_their_side_word():
    reader = fit_token_reader(TRAIN, 2, tokens, seed=0)
    assert [read_target(reader, tokens(s)) for s, _ in NEW] == [k for _, k in NEW]
    for sentence, _ in NEW:  # the side word gets the most attention
        weights = reader.attention(torch.as_tensor(tokens(sentence), dtype=torch.float32))
        side = [i for i, w in enumerate(sentence.split()) if w in ("left", "right")]
        assert int(weights.argmax()) in side


def test_the_reader_reads_only_the_words_its_training_saw():
    """An unseen word whose embedding lies near the other side's word drew the attention off
    the side word ("the right-side object please" read as left, issue 75); read by the words
    training saw, the sentence reads as its side word says."""
    WORDS["sidelong"] = 3.0 * WORDS["left"]  # a word no training sentence has
    try:
        sentence = "the right sidelong object"
        blind = fit_token_reader(TRAIN, 2, tokens, seed=0)
        assert read_target(blind, tokens(sentence), ids(sentence)) == 0  # reads every word
        reader = fit_token_reader(TRAIN, 2, tokens, seed=0, ids=ids)
        assert read_target(reader, tokens(sentence)) == 0  # no ids: every word, as before
        assert read_target(reader, tokens(sentence), ids(sentence)) == 1
        assert {w for w in WORDS if reader.seen[list(WORDS).index(w)]} == \
            {w for s, _ in TRAIN for w in s.split()}
        unknown = "hand me that"  # no word seen: read whole, never as nothing
        assert read_target(reader, tokens(unknown), ids(unknown)) in (0, 1)
        with pytest.raises(InvalidInputError, match=r"token ids"):
            read_target(reader, tokens(sentence), ids(sentence)[:2])
    finally:
        del WORDS["sidelong"]


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


# kqv's "tokens" reading: the reader trains at the first fit and decides each sentence's Query.
SCENE_WORDS = {word: _RNG.normal(size=EMBEDDING_SIZE) for word in (
    "red green blue the square please pick up grab that one hand me over there").split()}


def scene_tokens(sentence: str) -> np.ndarray:
    """Made-up (n, 384) token embeddings for the synthetic scenes' sentences."""
    return np.stack([SCENE_WORDS[w] for w in sentence.split()]).astype(np.float32)


def scene_ids(sentence: str) -> np.ndarray:
    """Made-up word-piece ids for the synthetic scenes' sentences."""
    return np.array([list(SCENE_WORDS).index(w) for w in sentence.split()])


@pytest.fixture
def scene_words(monkeypatch):
    """kqv reads the synthetic scenes' sentences by the made-up words, not the encoder."""
    monkeypatch.setattr("perception.language.sentence_reading.token_embeddings", scene_tokens)
    monkeypatch.setattr("perception.language.sentence_reading.token_ids", scene_ids)


def _worded_scenes(size: int, seed: int, fillers: tuple[str, ...]) -> Dataset:
    """Synthetic selected-type scenes, each naming its colour in a sentence; the sentence's
    pooled 'embedding' is random, unrelated to what it names, as a pooled vector can be."""
    base = synthetic_dataset(size=size, conditioned=True, seed=seed, image_px=48)
    rng = np.random.default_rng(seed)
    names = base.conditions.argmax(axis=1)
    sentences = [f"{rng.choice(fillers)} the {TYPES[k]} square" for k in names]
    rows = rng.normal(size=(size, EMBEDDING_SIZE))
    return given_as(base, ConditionKind.TEXT, rows / np.linalg.norm(rows, axis=1,
                                                                       keepdims=True),
                    sentences)


def test_auto_reads_types_by_prototype_and_other_targets_by_tokens():
    types = given_as(synthetic_dataset(4, conditioned=True), ConditionKind.TEXT,
                     np.eye(4, EMBEDDING_SIZE), ["the red square"] * 4)
    spec = ModelSpec.from_metadata(types.metadata)
    assert sentence_reading(spec, KqvConfig()) == "nearest"
    sides = replace(spec, condition_choices=("left", "right"))
    assert sentence_reading(sides, KqvConfig()) == "tokens"
    assert sentence_reading(sides, KqvConfig(sentence_reading="nearest")) == "nearest"
    assert KqvNet(spec, KqvConfig()).reader is None and \
        KqvNet(sides, KqvConfig()).reader is not None


def test_kqv_reads_a_new_wording_by_its_words_where_the_pooled_vector_says_nothing(
        tmp_path, monkeypatch, scene_words):
    train = _worded_scenes(24, seed=1, fillers=("pick up", "grab"))
    model = KqvModel.for_dataset(train, KqvConfig(seed=0, sentence_reading="tokens"))
    model.fit(train, TrainConfig(steps=2, batch_size=4, threads=1), progress=False)
    new = [Condition(ConditionKind.TEXT, f"hand me the {colour} square over there")
           for colour in TYPES]  # fillers never trained on
    rows = np.zeros((len(new), EMBEDDING_SIZE), np.float32)  # the pooled rows: not read
    read = model.condition_rows(new, rows)
    units = model.network.prototypes / model.network.prototypes.norm(dim=1, keepdim=True)
    np.testing.assert_allclose(read, units.numpy(), atol=1e-6)  # each colour its own Query
    image = train.images[0]
    monkeypatch.setattr("perception.interface.embed", lambda s: np.zeros(EMBEDDING_SIZE,
                                                                          np.float32))
    for k, condition in enumerate(new):  # predict() reads the words, as the rows say
        np.testing.assert_allclose(
            model.predict(image, condition).targets[0].position_m,
            model.predict_batch(image[None], read[k:k + 1])[0].targets[0].position_m)
    loaded = KqvModel.load(model.save(tmp_path / "ckpt"))
    np.testing.assert_array_equal(loaded.condition_rows(new, rows), read)
    for mine, theirs in zip(model.network.reader.parameters(),
                            loaded.network.reader.parameters(), strict=True):
        assert bool((mine == theirs).all())
    assert {id(p) for p in model.network.reader.parameters()}.isdisjoint(
        id(p) for p in model._pose_parameters())  # trained apart, before the pose
    seen = model.network.reader.seen
    assert int(seen.sum()) == len({w for i in range(len(train))
                                   for w in (train.condition(i).value or "").split()})
    # A checkpoint saved before the reader kept its words reads every word, as it was trained.
    folder = tmp_path / "ckpt"
    config = json.loads((folder / "config.json").read_text())
    save_checkpoint(folder, "kqv", {k: v for k, v in config.items() if k not in (
        "format_version", "model", "weights_sha256", "config_sha256")},
        {k: v for k, v in model.network.state_dict().items() if k != "reader.seen"})
    old = KqvModel.load(folder)
    assert bool((old.network.reader.seen == 1).all())
    assert old.condition_rows(new[:1], rows[:1]).shape == (1, EMBEDDING_SIZE)


def test_a_sentence_task_trains_and_predicts_as_its_one_hot_twin(scene_words):
    """Each training sentence trains as its named target's row and the Query form is the
    one-hot twin's: read right, a sentence model is the one-hot model (up to float rounding)."""
    text = _worded_scenes(16, seed=4, fillers=("pick up", "grab"))
    onehot = synthetic_dataset(16, conditioned=True, seed=4, image_px=48)
    train = TrainConfig(steps=30, batch_size=4, threads=1)
    twins = []
    for dataset in (onehot, text):
        config = KqvConfig(seed=0, starts=1, sentence_reading="tokens")
        model = KqvModel.for_dataset(dataset, config)
        model.fit(dataset, train, progress=False)
        rows = model.condition_rows([dataset.condition(i) for i in range(len(dataset))],
                                    dataset.conditions)
        twins.append([p.targets[0].position_m for p in model.predict_batch(dataset.images, rows)])
    np.testing.assert_allclose(twins[0], twins[1], atol=1e-4)


def test_a_side_sentence_checkpoint_from_before_the_twin_form_keeps_its_base_queries(
        tmp_path, scene_words):
    text = _worded_scenes(8, seed=4, fillers=("pick up", "grab"))
    sides = replace(text.metadata, extra={})  # no object types: its targets read as sides
    text = replace(text, metadata=sides)
    old = KqvModel.for_dataset(text, KqvConfig(seed=0, starts=1, query_mode="conditioned+base"))
    old.fit(text, TrainConfig(steps=2, batch_size=4, threads=1), progress=False)
    folder = old.save(tmp_path / "old")
    config = json.loads((folder / "config.json").read_text())
    config["hyperparameters"]["query_mode"] = "auto"  # as such a checkpoint was saved
    save_checkpoint(folder, "kqv", {k: v for k, v in config.items() if k not in (
        "format_version", "model", "weights_sha256", "config_sha256")},
        old.network.state_dict())
    loaded = KqvModel.load(folder)
    assert loaded.config.query_mode == "conditioned+base"
    assert KqvNet(loaded.spec, KqvConfig()).base_queries is None  # today's auto: a side's form


def test_a_sentence_task_over_types_trains_mirrored_where_its_dataset_allows(scene_words):
    """The mirror flips the image and keeps the sentence: a type is the same in the mirror."""
    base = synthetic_dataset(8, conditioned=True, seed=4, camera=CAMERA)  # on the mirror plane
    names = base.conditions.argmax(axis=1)
    rows = np.random.default_rng(4).normal(size=(8, EMBEDDING_SIZE))
    text = given_as(base, ConditionKind.TEXT, rows / np.linalg.norm(rows, axis=1, keepdims=True),
                    [f"grab the {TYPES[k]} square" for k in names])
    text = replace(text, metadata=replace(text.metadata,
                                          extra=text.metadata.extra | {MIRROR_FLAG: True}))
    model = KqvModel.for_dataset(text, KqvConfig(seed=0, starts=1))
    model.fit(text, TrainConfig(steps=2, batch_size=4, threads=1), progress=False)
    assert model._mirror is not None and model._mirror.rows is None
