"""Conditions given as a sentence or a picture: their checks, datasets of them, and kqv on them.

The sentence encoder itself is tested in test_sentences.py; here a sentence's vector is any
unit vector, which is all a model sees of it.
"""

from __future__ import annotations

import json
import re
from dataclasses import replace

import numpy as np
import pytest
import torch
from user_models import (
    CAMERA,
    TYPES,
    colour_picture,
    given_as,
    spec,
    synthetic_dataset,
    trained_scaler,
)

from perception.interface import (
    NO_CONDITION,
    PICTURE_PX,
    Condition,
    ConditionKind,
    InvalidInputError,
    LabelKind,
    PerceptionModel,
    Prediction,
    Target,
    condition_size,
)
from perception.labels import label_vector
from perception.learning.checkpoint import save_checkpoint
from perception.learning.data import Dataset
from perception.learning.dataset_file import load_dataset, save_dataset
from perception.learning.evaluate import evaluate
from perception.learning.train import Batch, TrainConfig, train
from perception.models.kqv import KqvConfig, KqvModel

PICTURE = np.full((PICTURE_PX, PICTURE_PX, 3), 200, np.uint8)


def test_a_text_condition_is_a_sentence_and_nothing_else():
    assert Condition(ConditionKind.TEXT, "pick up the red mug").value == "pick up the red mug"
    for value in (None, "", "   ", "x" * 501):
        with pytest.raises(InvalidInputError, match=r"condition\.value"):
            Condition(ConditionKind.TEXT, value)
    with pytest.raises(InvalidInputError, match=r"condition.choices = .* \(\) when kind is "
                                                r"'text'"):
        Condition(ConditionKind.TEXT, "the mug", ("mug",))
    with pytest.raises(InvalidInputError, match=r"condition\.picture"):
        Condition(ConditionKind.TEXT, "the mug", picture=PICTURE)


def test_an_image_condition_is_named_by_its_pictures_hash():
    first = Condition(ConditionKind.IMAGE, picture=PICTURE)
    assert first.value.startswith("picture ") and len(first.value) == len("picture ") + 12
    assert first == Condition(ConditionKind.IMAGE, picture=PICTURE.copy())
    other = PICTURE.copy()
    other[0, 0] = 0
    assert first != Condition(ConditionKind.IMAGE, picture=other)
    assert not first.picture.flags.writeable  # a copy, frozen: the caller's array may change
    vector = first.vector()
    assert vector.shape == (condition_size(ConditionKind.IMAGE, ()),) == (3 * 32 * 32,)
    assert vector.dtype == np.float32 and np.allclose(vector, 200 / 255)
    for picture, found in ((None, "NoneType"), (PICTURE[:16], "uint8 (16, 32, 3)"),
                           (PICTURE.astype(float), "float64")):
        with pytest.raises(InvalidInputError, match=rf"condition.picture = '{re.escape(found)}"):
            Condition(ConditionKind.IMAGE, picture=picture)


def test_one_hot_conditions_are_unchanged():
    condition = Condition(ConditionKind.SIDE, "right", ("left", "right"))
    assert condition.vector().tolist() == [0.0, 1.0]
    assert Condition().vector().shape == (0,)
    assert condition_size(ConditionKind.OBJECT_TYPE, TYPES) == 3
    assert condition_size(ConditionKind.TEXT, TYPES) == 384


def _unit_rows(count: int, seed: int) -> np.ndarray:
    rows = np.random.default_rng(seed).normal(size=(count, 384))
    return (rows / np.linalg.norm(rows, axis=1, keepdims=True)).astype(np.float32)


def _text_dataset(size: int, seed: int) -> Dataset:
    """The synthetic selected-type scenes, each type named by one fixed random 'sentence'."""
    base = synthetic_dataset(size=size, conditioned=True, seed=seed)
    names = base.conditions.argmax(axis=1)
    return given_as(base, ConditionKind.TEXT, _unit_rows(len(TYPES), 0)[names],
                    [f"the {TYPES[k]} square" for k in names])


def test_a_text_dataset_keeps_sentences_and_names(tmp_path):
    dataset = _text_dataset(6, seed=1)
    assert dataset.condition_names() == tuple(TYPES[k] for k in
                                              synthetic_dataset(6, conditioned=True, seed=1)
                                              .conditions.argmax(axis=1))
    assert dataset.condition(2) == Condition(ConditionKind.TEXT,
                                             f"the {dataset.condition_names()[2]} square")
    assert load_dataset(save_dataset(dataset, tmp_path / "text.gva")) == dataset
    bad = dataset.conditions.copy()
    bad[3] *= 2
    with pytest.raises(InvalidInputError, match=r"conditions\[3\] .* a sentence embedding of "
                                                r"unit length"):
        Dataset(dataset.metadata, dataset.images, bad, dataset.labels, dataset.scenes)
    wrong = tuple(record | {"condition": {"value": "purple"}} for record in dataset.scenes)
    with pytest.raises(InvalidInputError, match=r"scenes\[0\].condition.value = 'purple'"):
        Dataset(dataset.metadata, dataset.images, dataset.conditions, dataset.labels,
                wrong).condition_names()


def test_an_image_dataset_gives_back_each_picture():
    base = synthetic_dataset(size=4, conditioned=True, seed=2)
    rng = np.random.default_rng(0)
    pictures = [colour_picture(int(k), rng) for k in base.conditions.argmax(axis=1)]
    rows = np.stack([Condition(ConditionKind.IMAGE, picture=p).vector() for p in pictures])
    dataset = given_as(base, ConditionKind.IMAGE, rows, [None] * 4)
    for n, picture in enumerate(pictures):
        assert np.array_equal(dataset.condition(n).picture, picture)
    with pytest.raises(InvalidInputError, match=r"a picture's pixels in \[0, 1\]"):
        Dataset(dataset.metadata, dataset.images, rows * 2, dataset.labels, dataset.scenes)


def test_kqv_reads_a_sentence_vector_and_checks_the_condition_it_is_given(tmp_path):
    dataset = _text_dataset(6, seed=3)
    model = KqvModel.for_dataset(dataset, KqvConfig(seed=0))
    model.fit(dataset, TrainConfig(steps=2, batch_size=4, threads=1), progress=False)
    assert model.spec.condition_size == 384
    loaded = KqvModel.load(model.save(tmp_path / "ckpt"))
    image = dataset.images[0]
    vector = dataset.conditions[0]
    # predict() takes the Condition and reads its vector; the loaded model predicts the same.
    np.testing.assert_allclose(
        loaded.predict_batch(image[None], vector[None])[0].targets[0].position_m,
        model.predict_batch(image[None], vector[None])[0].targets[0].position_m, atol=1e-6)
    with pytest.raises(InvalidInputError, match=r"condition = .* a text condition$"):
        model.predict(image, Condition(ConditionKind.OBJECT_TYPE, "red", TYPES))


def test_a_datasets_prototypes_count_each_distinct_sentence_once():
    base = synthetic_dataset(size=12, conditioned=True, seed=6)
    names = base.conditions.argmax(axis=1)
    often = int(np.bincount(names, minlength=len(TYPES)).argmax())  # asked 3 times or more
    rows = _unit_rows(len(TYPES), 0)[names]
    other = _unit_rows(1, 1)[0]
    rows[np.flatnonzero(names == often)[0]] = other  # one sample words it otherwise
    dataset = given_as(base, ConditionKind.TEXT, rows, [None] * len(names))
    prototypes = dataset.condition_prototypes()
    np.testing.assert_allclose(prototypes[often], (_unit_rows(len(TYPES), 0)[often] + other) / 2,
                               atol=1e-7)  # each wording once, however often it was asked
    one = dataset.subset([0])
    assert not np.delete(one.condition_prototypes(), names[0], axis=0).any()  # never named


def _worded(size: int, seed: int, wordings: range) -> Dataset:
    """Synthetic selected-type scenes; each names its type by one of several wordings.

    A wording is its type's direction plus as much noise again (cosine about 0.7 to it), as a
    sentence encoder places different wordings of one thing near each other.
    """
    base = synthetic_dataset(size=size, conditioned=True, seed=seed, image_px=48)
    meaning = _unit_rows(len(TYPES), 7)
    noise = _unit_rows(len(TYPES) * 8, 8).reshape(len(TYPES), 8, 384)
    rng = np.random.default_rng(seed)
    names = base.conditions.argmax(axis=1)
    chosen = rng.choice(list(wordings), size=size)
    rows = meaning[names] + noise[names, chosen]
    rows /= np.linalg.norm(rows, axis=1, keepdims=True)
    return given_as(base, ConditionKind.TEXT, rows,
                    [f"wording {w} of {TYPES[k]}" for k, w in zip(names, chosen, strict=True)])


def test_kqv_reads_wordings_it_never_saw_by_their_likeness_to_the_trained_ones(tmp_path):
    train, test = _worded(48, seed=4, wordings=range(3)), _worded(24, seed=5, wordings=range(3, 8))
    model = KqvModel.for_dataset(train, KqvConfig(seed=0))
    model.fit(train, TrainConfig(steps=300, batch_size=16, learning_rate=3e-3, threads=1),
              progress=False)
    weights = model.network.sentence_weights(torch.from_numpy(test.conditions)).numpy()
    named = [TYPES.index(name) for name in test.condition_names()]
    assert (weights.argmax(axis=1) == named).all()  # every new wording read as its type
    with torch.no_grad():  # ... and given that type's own Query, as its trained wordings are
        queries = model.network.queries(torch.from_numpy(test.conditions))
        first = [train.condition_names().index(name) for name in test.condition_names()]
        torch.testing.assert_close(queries, model.network.queries(
            torch.from_numpy(train.conditions[first])), rtol=0, atol=0)
    result = evaluate(model, test)
    assert result.mean_position_error_cm < 5.0, result.headline()  # chance: about 15 cm
    loaded = KqvModel.load(model.save(tmp_path / "ckpt"))
    assert loaded.network.prototypes is not None
    np.testing.assert_array_equal(loaded.network.prototypes.numpy(),
                                  train.condition_prototypes())
    # A checkpoint from before prototypes read the embedding itself, and still loads so.
    legacy = KqvModel.for_dataset(train, KqvConfig(seed=0, sentence_reading="embedding"))
    legacy.fit(train, TrainConfig(steps=2, batch_size=4, threads=1), progress=False)
    folder = legacy.save(tmp_path / "legacy")
    config = json.loads((folder / "config.json").read_text())
    del config["hyperparameters"]["sentence_reading"]
    save_checkpoint(folder, "kqv", {k: v for k, v in config.items() if k not in
                                    ("format_version", "model", "weights_sha256",
                                     "config_sha256")}, legacy.network.state_dict())
    assert KqvModel.load(folder).config.sentence_reading == "embedding"


def test_a_training_sentence_read_as_another_target_still_trains_its_named_targets_query():
    """MiniLM puts "left" near "right": such a sentence must not train the other side's Query."""
    dataset = _worded(24, seed=4, wordings=range(3))
    names = dataset.condition_names()
    misread, other = 0, TYPES[(TYPES.index(names[0]) + 1) % len(TYPES)]
    twin = next(n for n, name in enumerate(names) if name == other)
    rows = dataset.conditions.copy()
    rows[misread] = rows[twin]  # named names[0], worded as `other` is
    dataset = replace(dataset, conditions=rows)
    model = KqvModel.for_dataset(dataset, KqvConfig(seed=0))
    asked: list[tuple[torch.Tensor, torch.Tensor]] = []
    loss = model.batch_loss

    def recording(batch: Batch) -> torch.Tensor:
        asked.append((batch.conditions.clone(), batch.labels.clone()))
        return loss(batch)

    model.batch_loss = recording  # type: ignore[method-assign]
    model.fit(dataset, TrainConfig(steps=6, batch_size=24, threads=1), progress=False)
    net = model.network
    with torch.no_grad():  # the premise: as asked, the sentence reads as the other target
        reading = net.sentence_weights(torch.from_numpy(rows[[misread]])).argmax(dim=1)
    assert TYPES[int(reading[0])] == other
    labels, seen = torch.from_numpy(dataset.labels), set()
    for conditions, batch_labels in asked:  # each sample by its labels, which are its own
        samples = [int(np.flatnonzero((labels == row).flatten(1).all(dim=1))[0])
                   for row in batch_labels]
        with torch.no_grad():
            trained_as = net.sentence_weights(conditions).argmax(dim=1).tolist()
        assert [TYPES[k] for k in trained_as] == [names[n] for n in samples]
        seen.update(samples)
    assert misread in seen


def test_the_prototypes_reading_mixes_the_targets_queries_by_the_sentences_weights():
    train = _worded(12, seed=4, wordings=range(3))
    model = KqvModel.for_dataset(train, KqvConfig(seed=0, sentence_reading="prototypes",
                                                  sentence_temperature=1.0))  # soft: blends
    model.fit(train, TrainConfig(steps=5, batch_size=4, threads=1), progress=False)
    net, rows = model.network, torch.from_numpy(_worded(6, seed=5, wordings=range(3, 8))
                                                .conditions)
    with torch.no_grad():
        # (k, q, Ck + 2): each target's own Query, what its one-hot condition would get
        own = net.base_queries + net.query_mlp(torch.eye(len(TYPES))).view(len(TYPES), 1, -1)
        weights = net.sentence_weights(rows)  # (B, k)
        assert bool((weights.max(dim=1).values < 1).all())  # blends, not one-hot readings
        torch.testing.assert_close(net.queries(rows),
                                   torch.einsum("bk,kqc->bqc", weights, own), atol=1e-5, rtol=0)


@pytest.mark.parametrize("noise", [0.0, 0.05])
def test_training_jitters_sentences_only_when_asked(noise):
    """Sentence noise (for a model that reads the embedding) is off unless set."""
    assert TrainConfig().sentence_noise == 0.0
    dataset = _text_dataset(6, seed=3)
    seen: list[torch.Tensor] = []
    weight = torch.nn.Parameter(torch.zeros(1))

    def loss(batch: Batch) -> torch.Tensor:
        seen.append(batch.conditions.clone())
        return (weight - 1).square().sum()

    train(torch.nn.Module(), loss, dataset, TrainConfig(steps=3, batch_size=6, threads=1,
                                                        sentence_noise=noise),
          progress=False, parameters=[weight])
    asked = torch.cat(seen)  # (18, 384), each a row of the dataset, jittered or not
    torch.testing.assert_close(asked.norm(dim=1), torch.ones(len(asked)))
    cosines = (asked @ torch.from_numpy(dataset.conditions).T).max(dim=1).values
    if noise == 0:
        torch.testing.assert_close(cosines, torch.ones(len(asked)))
    else:  # 0.05 per dimension in 384: about 0.7 of the sentence's own direction is left
        assert 0.6 < float(cosines.mean()) < 0.8


def test_kqv_learns_to_attend_to_the_pictured_colour_in_pictures_it_never_saw():
    """Pictures of each colour (shades, places, backgrounds vary) steer the attention."""
    rng = np.random.default_rng(0)

    def pictured(size: int, seed: int) -> Dataset:
        base = synthetic_dataset(size=size, conditioned=True, seed=seed, image_px=48)
        rows = np.stack([Condition(ConditionKind.IMAGE, picture=colour_picture(int(k), rng))
                         .vector() for k in base.conditions.argmax(axis=1)])
        return given_as(base, ConditionKind.IMAGE, rows, [None] * size)

    train, test = pictured(48, seed=4), pictured(24, seed=5)
    model = KqvModel.for_dataset(train, KqvConfig(seed=0))
    assert model.network.picture_net is not None and spec().condition_size == 0
    model.fit(train, TrainConfig(steps=300, batch_size=16, learning_rate=3e-3, threads=1),
              progress=False)
    result = evaluate(model, test)
    # The images span 0.3 m: chance (a random one of three squares) is about 15 cm off.
    assert result.mean_position_error_cm < 5.0, result.headline()


class _PointsAt(PerceptionModel):
    """Attends, image after image, to the pixels it is handed (a stand-in for a model)."""

    name = "points-at"
    label_kind = LabelKind.POSITION

    def __init__(self, points_px: list[np.ndarray]) -> None:
        self.points = iter(points_px)

    def predict(self, image, condition=NO_CONDITION):
        return Prediction((Target(np.zeros(3)),), next(self.points)[None])


def test_attention_on_the_named_object_is_scored_per_image_and_per_scene():
    """Two scenes of three objects, each asked for all three: the model misses once."""
    xy = [[(0.35, 0.10), (0.45, -0.05), (0.55, 0.08)], [(0.40, -0.12), (0.50, 0.12), (0.38, 0.0)]]
    scenes, labels, points = [], [], []
    for s, objects in enumerate(xy):
        for target in range(3):
            scenes.append({"index": s, "targets": [target],
                           "objects": [{"type": TYPES[k], "position_xy_m": list(p)}
                                       for k, p in enumerate(objects)],
                           "condition": {"kind": "object_type", "value": TYPES[target]}})
            labels.append(label_vector(np.array([[*objects[target], 0.02]])))
            aimed = objects[target] if (s, target) != (1, 2) else objects[0]  # one miss
            points.append(CAMERA.project(np.array([[*aimed, 0.02]]))[0])
    base = synthetic_dataset(size=6, conditioned=True)
    metadata = replace(base.metadata, camera=CAMERA.to_json())
    dataset = Dataset(metadata, base.images, np.eye(3, dtype=np.float32)[[0, 1, 2] * 2],
                      np.array(labels, np.float32), tuple(scenes))
    result = evaluate(_PointsAt(points), dataset)
    assert result.attention_on_named_fraction == pytest.approx(5 / 6)
    assert result.attention_switch_fraction == pytest.approx(1 / 2)
    untied = type("KeyPointsAt", (_PointsAt,), {"attention_per_target": False})  # keypoint-min
    assert evaluate(untied(points), dataset).attention_on_named_fraction is None
    unconditioned = evaluate(trained_scaler(KqvModel.for_dataset(synthetic_dataset(size=2))),
                             synthetic_dataset(size=2))
    assert unconditioned.attention_on_named_fraction is None
