"""kqv's type head: it states the object type each attention head sees, and changes no pose."""

from dataclasses import replace

import numpy as np
import pytest
import torch
from user_models import BACKGROUND, TYPES, spec, trained_scaler, typed_dataset

from perception.interface import InvalidInputError, LabelKind
from perception.learning.learnable import ModelSpec
from perception.learning.mirror import Mirror
from perception.learning.torch_pieces import images_to_tensor
from perception.learning.train import Batch, TrainConfig
from perception.models.kqv import KqvConfig, KqvModel


@pytest.fixture(scope="module")
def typed_model():
    """A kqv model with a type head, trained on 16 typed scenes (300 steps: its type head is
    trained as many, at most, and learns the types in about that many)."""
    train = typed_dataset(16, seed=0)
    model = KqvModel.for_dataset(train, KqvConfig(starts=1, warmup_steps=0))
    model.fit(train, TrainConfig(steps=300, batch_size=8, threads=1, log_every=10),
              progress=False)
    return model, train


@pytest.mark.slow
def test_the_type_head_states_the_type_it_attends_to_in_untrained_scenes(typed_model):
    model, _ = typed_model
    test = typed_dataset(32, seed=1)
    assert model.spec.object_types == TYPES and model.network.type_head is not None
    stated = [p.targets[0].object_type for p in model.predict_batch(test.images,
                                                                   test.conditions)]
    true = [row[0] for row in test.target_types()]
    assert len(set(true)) == 3  # every type among the untrained scenes
    assert np.mean([s == t for s, t in zip(stated, true, strict=True)]) >= 0.9, (stated, true)
    report = model.report
    assert [(p.name, p.steps) for p in report.phases] == [("targets", 300), ("object types", 300)]
    assert report.steps == 600 and report.final_loss == report.phases[0].final_loss
    assert report.phases[1].final_loss < 0.55  # cross-entropy: half of a guess's log 3 = 1.1


def test_the_type_head_leaves_the_pose_weights_as_they_would_be_without_it():
    dataset = typed_dataset(4, seed=2)
    config = TrainConfig(steps=5, batch_size=2, threads=1)
    weights, reports, initial = {}, {}, {}
    for head in (None, False):  # None: on, for grasp labels of named types
        model = KqvModel.for_dataset(dataset, KqvConfig(type_head=head, type_steps=4, starts=2,
                                                        start_steps=2, warmup_steps=3))
        initial[head] = {k: v.clone() for k, v in model.network.state_dict().items()}
        reports[head] = model.fit(dataset, config, progress=False)
        weights[head] = model.network.state_dict()
    with_head, without = weights[None], weights[False]
    head_keys = {k for k in with_head if k.startswith("type_head.")}
    assert head_keys and set(with_head) - head_keys == set(without)
    for key, value in without.items():
        assert torch.equal(with_head[key], value), key  # bitwise
    assert not all(torch.equal(with_head[k], initial[None][k]) for k in head_keys)  # trained
    assert reports[None].final_loss == reports[False].final_loss  # the start choice saw the same
    assert [p.name for p in reports[False].phases] == ["starts", "targets"]
    assert [p.name for p in reports[None].phases] == ["starts", "targets", "object types"]
    assert reports[None].steps == 5 + 4 and reports[None].phases[0].steps == 2
    assert sum(p.wall_time_s for p in reports[None].phases) == pytest.approx(
        reports[None].wall_time_s)


def test_a_short_training_trains_the_type_head_no_more_steps_than_asked():
    """Issue 65: a 3-step training spent 300 steps on the type head; ``type_steps`` or more
    train it ``type_steps``, as before."""
    dataset = typed_dataset(4, seed=3)
    for steps, type_steps, trained in ((3, 300, 3), (6, 4, 4), (4, 4, 4)):
        model = KqvModel.for_dataset(dataset, KqvConfig(type_steps=type_steps, starts=1,
                                                        warmup_steps=0))
        report = model.fit(dataset, TrainConfig(steps=steps, batch_size=2, threads=1),
                           progress=False)
        assert [(p.name, p.steps) for p in report.phases] == [("targets", steps),
                                                              ("object types", trained)]


def test_the_type_head_is_built_for_grasp_specs_that_name_their_types():
    named = replace(spec(kind=LabelKind.GRASP_POSE), object_types=TYPES)
    assert KqvModel(named).network.type_head is not None
    assert KqvModel(spec(kind=LabelKind.GRASP_POSE)).network.type_head is None  # none named
    assert KqvModel(replace(named, label_kind=LabelKind.POSITION)).network.type_head is None
    assert KqvModel(replace(named, label_kind=LabelKind.POSITION),
                    KqvConfig(type_head=True)).network.type_head is not None
    assert KqvModel(named, KqvConfig(type_head=False)).network.type_head is None
    with pytest.raises(InvalidInputError, match=r"type_head = True is not allowed: None or "
                                                 r"False for a dataset that names no object"):
        KqvModel(spec(kind=LabelKind.GRASP_POSE), KqvConfig(type_head=True))
    with pytest.raises(InvalidInputError, match=r"type_steps = 0 is not allowed: an integer >= 1"):
        KqvConfig(type_steps=0)
    with pytest.raises(InvalidInputError, match=r"type_head = 'yes' is not allowed: None, True"):
        KqvConfig(type_head="yes")  # type: ignore[arg-type]
    with pytest.raises(InvalidInputError, match=r"object_types = \('mug', 'mug'\) is not "
                                                 r"allowed: distinct non-empty strings"):
        replace(named, object_types=("mug", "mug"))


def test_a_type_condition_states_its_own_type_and_other_models_what_their_head_sees():
    images = np.broadcast_to(BACKGROUND, (3, 64, 64, 3)).copy()
    conditioned = trained_scaler(KqvModel(replace(spec(kind=LabelKind.GRASP_POSE, choices=TYPES),
                                                  object_types=TYPES)))
    assert conditioned.network.type_head is None  # the condition names the type: no head
    stated = conditioned.predict_batch(images, np.eye(3, dtype=np.float32)[[2, 0, 1]])
    assert [p.targets[0].object_type for p in stated] == ["blue", "red", "green"]
    model = trained_scaler(KqvModel(replace(spec(q=2, kind=LabelKind.GRASP_POSE),
                                            object_types=("mug", "sponge"))))
    with torch.no_grad():  # the head's last layer says "sponge" whatever it reads
        last = model.network.type_head[-1][-1]
        last.weight.zero_()
        last.bias.copy_(torch.tensor([0.0, 1.0]))
    stated = model.predict_batch(images, np.zeros((3, 0), np.float32))
    assert [t.object_type for p in stated for t in p.targets] == ["sponge"] * 6
    blind = trained_scaler(KqvModel(spec(kind=LabelKind.GRASP_POSE)))
    assert blind.predict_batch(images, np.zeros((3, 0)))[0].targets[0].object_type is None


def test_a_batch_keeps_its_type_indices_through_the_mirror():
    dataset = typed_dataset(4, seed=3)
    batch = Batch(images_to_tensor(dataset.images), torch.as_tensor(dataset.conditions),
                  torch.as_tensor(dataset.labels), torch.as_tensor(dataset.target_type_indices()))
    mirrored = Mirror(ModelSpec.from_metadata(dataset.metadata), seed=0)(
        batch, flip=torch.tensor([True, False, True, True]))
    assert not torch.equal(mirrored.labels, batch.labels)  # mirrored, but the types stay
    assert torch.equal(mirrored.type_indices, batch.type_indices)
    assert Batch(batch.images, batch.conditions, batch.labels).type_indices is None
