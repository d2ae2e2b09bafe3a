import dataclasses
import json
import re

import numpy as np
import pytest
import torch
from user_models import TYPES, CentreModel, synthetic_dataset, typed_dataset

from experiments.cli import main
from perception.interface import (
    NO_CONDITION,
    Condition,
    InvalidInputError,
    LabelKind,
    PerceptionModel,
    Prediction,
    Target,
)
from perception.labels import split_label
from perception.learning.dataset_file import save_dataset
from perception.learning.evaluate import evaluate, label_mean_error_cm
from perception.learning.learnable import ModelSpec
from perception.learning.torch_pieces import LabelScaler
from perception.learning.train import (
    TrainConfig,
    TrainReport,
    available_threads,
    batch_indices,
    default_threads,
    train,
)
from perception.models.kqv import KqvConfig, KqvModel

FAST = TrainConfig(steps=60, batch_size=8, learning_rate=3e-3, log_every=10, threads=1)


@pytest.mark.parametrize("kind", [LabelKind.POSITION, LabelKind.GRASP_POSE])
def test_loss_falls_on_a_tiny_synthetic_dataset(kind):
    dataset = synthetic_dataset(size=8, kind=kind, seed=1)
    model = KqvModel.for_dataset(dataset, KqvConfig(seed=0, warmup_steps=0))  # the loop under test
    report = model.fit(dataset, FAST, progress=False)
    first, last = report.losses[0][1], report.final_loss
    assert last < 0.5 * first, report.losses
    assert report.steps == 60 and report.samples == 8 and len(report.losses) == 6
    assert report.wall_time_s > 0 and report.threads == 1
    json.dumps(report.to_json())  # JSON-able as it is


def test_conditioned_model_trains_and_evaluates():
    dataset = synthetic_dataset(size=8, conditioned=True, seed=2)
    model = KqvModel.for_dataset(dataset)
    model.scaler = LabelScaler.fit(dataset.labels[..., :3])  # what fit would choose
    before = evaluate(model, dataset)
    model.fit(dataset, FAST, progress=False)
    after = evaluate(model, dataset)
    assert after.mean_position_error_cm < before.mean_position_error_cm


def test_training_is_reproducible_from_its_seeds():
    dataset = synthetic_dataset(size=4, seed=3)
    config = TrainConfig(steps=5, batch_size=2, log_every=1, threads=1)
    curves = []
    for _ in range(2):
        model = KqvModel.for_dataset(dataset, KqvConfig(seed=7))
        curves.append(model.fit(dataset, config, progress=False).losses)
    assert curves[0] == curves[1]


def test_batches_visit_every_sample_once_per_epoch():
    batches = batch_indices(10, 4, np.random.default_rng(0))
    drawn = np.concatenate([next(batches) for _ in range(5)])  # 20 = two epochs
    assert sorted(drawn[:10]) == list(range(10)) and sorted(drawn[10:]) == list(range(10))
    assert len(next(batch_indices(3, 8, np.random.default_rng(0)))) == 3  # capped at the size


def test_train_config_errors_name_field_value_and_allowed():
    with pytest.raises(InvalidInputError, match=r"steps = 0 is not allowed: an integer >= 1"):
        TrainConfig(steps=0)
    with pytest.raises(InvalidInputError, match=r"learning_rate = -0.1 is not allowed"):
        TrainConfig(learning_rate=-0.1)
    with pytest.raises(InvalidInputError, match=r"lr_schedule = 'step' is not allowed"):
        TrainConfig(lr_schedule="step")
    with pytest.raises(InvalidInputError, match=r"device = 'gpu0' is not allowed"):
        TrainConfig(device="gpu0")


def test_fit_refuses_a_dataset_of_another_spec():
    model = KqvModel.for_dataset(synthetic_dataset(size=2, targets=1))
    with pytest.raises(InvalidInputError, match=r"targets is 3, the model's is 1"):
        model.fit(synthetic_dataset(size=2, targets=3), FAST, progress=False)


class Truth(PerceptionModel):
    """Predicts a dataset's own labels, its rotations turned half a turn about the TCP z axis."""

    name = "truth"
    label_kind = LabelKind.GRASP_POSE

    def __init__(self, dataset):
        self.labels = {image.tobytes(): label
                       for image, label in zip(dataset.images, dataset.labels, strict=True)}

    def predict(self, image: np.ndarray, condition: Condition = NO_CONDITION) -> Prediction:
        position, rotation = split_label(self.labels[image.tobytes()].astype(np.float64))
        flip = np.diag([-1.0, -1.0, 1.0])
        offset = np.array([0.0, 0.03, 0.04])
        return Prediction(tuple(Target(p + offset, r @ flip)
                                for p, r in zip(position, rotation, strict=True)))


def test_evaluate_reports_cm_and_symmetric_angles():
    dataset = synthetic_dataset(size=5, targets=2, kind=LabelKind.GRASP_POSE, seed=4)
    result = evaluate(Truth(dataset), dataset)
    assert result.samples == 5 and result.targets == 2
    assert result.mean_position_error_cm == pytest.approx(5.0)  # 3-4-5 cm off
    assert result.mean_angle_error_deg == pytest.approx(0.0, abs=1e-4)
    assert np.shape(result.position_errors_cm) == (5, 2)
    assert len(result.per_target_mean_position_error_cm) == 2
    text = json.dumps(result.to_json())
    assert json.loads(text)["median_position_error_cm"] == pytest.approx(5.0)
    assert "5.00 cm" in result.headline()


class Spread(Truth):
    """The truth, with a heatmap per target: uniform over 4 x 4 cells, or one cell."""

    def __init__(self, dataset, uniform):
        super().__init__(dataset)
        self.uniform = uniform

    def predict(self, image, condition=NO_CONDITION):
        heatmap = np.full((4, 4), 1 / 16)
        if not self.uniform:
            heatmap = np.zeros((4, 4))
            heatmap[0, 0] = 1.0
        prediction = super().predict(image, condition)
        return dataclasses.replace(prediction, heatmaps=np.stack([heatmap] * 2))


class KeyPoints(Truth):
    """The truth, with 16 heatmaps tied to no target: 15 on one cell, one uniform."""

    attention_per_target = False

    def predict(self, image, condition=NO_CONDITION):
        sharp = np.zeros((15, 4, 4))
        sharp[:, 0, 0] = 1.0
        maps = np.concatenate([sharp, np.full((1, 4, 4), 1 / 16)])  # (16, 4, 4)
        return dataclasses.replace(super().predict(image, condition), heatmaps=maps,
                                   attention_px=np.zeros((16, 2)))


def test_the_entropy_of_heatmaps_tied_to_no_target_counts_every_one():
    """16 key points for 1 or 2 targets: every map of every image, never zipped to a target."""
    for targets in (1, 2):
        dataset = synthetic_dataset(size=3, targets=targets, kind=LabelKind.GRASP_POSE)
        result = evaluate(KeyPoints(dataset), dataset)
        assert result.median_heatmap_entropy_nats == pytest.approx(0.0, abs=1e-9)  # 15 of 16


def test_a_prediction_names_the_shape_of_bad_attention():
    target = (Target(np.zeros(3)),)
    with pytest.raises(InvalidInputError, match=r"attention_px = \(4,\) is not allowed: shape"):
        Prediction(target, np.zeros(4))
    with pytest.raises(InvalidInputError, match=r"heatmaps = \(4, 4\) is not allowed"):
        Prediction(target, heatmaps=np.zeros((4, 4)))


def test_evaluate_reports_the_heatmaps_entropy_and_each_condition():
    dataset = synthetic_dataset(size=5, targets=2, kind=LabelKind.GRASP_POSE, seed=4)
    assert evaluate(Spread(dataset, True), dataset).median_heatmap_entropy_nats == \
        pytest.approx(np.log(16))
    assert evaluate(Spread(dataset, False), dataset).median_heatmap_entropy_nats == \
        pytest.approx(0.0, abs=1e-9)
    assert evaluate(Truth(dataset), dataset).median_heatmap_entropy_nats is None
    assert evaluate(Truth(dataset), dataset).per_condition_mean_position_error_cm is None
    conditioned = synthetic_dataset(size=9, conditioned=True, kind=LabelKind.GRASP_POSE, seed=4)
    per = evaluate(Truth(conditioned), conditioned).per_condition_mean_position_error_cm
    drawn = {TYPES[i] for i in conditioned.conditions.argmax(1)}
    assert set(per) == drawn and all(e == pytest.approx(5.0) for e in per.values())


def test_evaluate_refuses_models_that_do_not_fit_the_dataset():
    grasps = synthetic_dataset(size=2, kind=LabelKind.GRASP_POSE)
    with pytest.raises(InvalidInputError, match=r"model rotation = None is not allowed"):
        evaluate(CentreModel(), grasps)
    with pytest.raises(InvalidInputError, match=r"model targets = \[1\] is not allowed: 3"):
        evaluate(CentreModel(), synthetic_dataset(size=2, targets=3))


def _with_positions(dataset, positions_m, choices):
    """``dataset`` with these (N, 1, 3) positions and these condition indices."""
    import dataclasses

    from perception.labels import label_vector

    n = len(positions_m)
    kept = dataset.subset(range(n))
    conditions = np.eye(kept.conditions.shape[1], dtype=np.float32)[list(choices)]
    return dataclasses.replace(kept, labels=label_vector(np.array(positions_m)),
                               conditions=conditions)


def test_the_no_image_reference_predicts_the_training_mean_per_condition():
    base = synthetic_dataset(size=4, conditioned=True, seed=1)  # one target, three types
    train = _with_positions(base, [[[0.0, 0.0, 0.0]], [[0.2, 0.0, 0.0]], [[0.0, 0.3, 0.0]]],
                            [0, 0, 1])
    # type 0 -> mean (0.1, 0, 0): 4 cm off; type 1 -> (0, 0.3, 0): exact; type 2 is never
    # trained -> the overall mean (0.0667, 0.1, 0): 10 cm off in y, 6.67 cm in x.
    test = _with_positions(base, [[[0.1, 0.0, 0.04]], [[0.0, 0.3, 0.0]],
                                  [[0.2 / 3, 0.0, 0.0]]], [0, 1, 2])
    assert label_mean_error_cm(train, test) == pytest.approx((4.0 + 0.0 + 10.0) / 3)
    unconditioned = synthetic_dataset(size=3, seed=2)
    mean_m = split_label(unconditioned.labels).position_m.mean(axis=0)
    expected_cm = 100 * np.linalg.norm(split_label(unconditioned.labels).position_m - mean_m,
                                       axis=-1).mean()
    assert label_mean_error_cm(unconditioned, unconditioned) == pytest.approx(expected_cm)
    with pytest.raises(InvalidInputError, match=r"test task = 'multiple' is not allowed"):
        label_mean_error_cm(train, unconditioned)



class Typed(PerceptionModel):
    """A top-down grasp at the table centre per target, stating the dataset's own target types.

    ``stated`` maps (image bytes, target index) to the type stated instead of the true one.
    """

    name = "typed"
    label_kind = LabelKind.GRASP_POSE

    def __init__(self, dataset, stated=None):
        self.types = {image.tobytes(): row
                      for image, row in zip(dataset.images, dataset.target_types(), strict=True)}
        self.stated = stated or {}

    def predict(self, image: np.ndarray, condition: Condition = NO_CONDITION) -> Prediction:
        key = image.tobytes()
        return Prediction(tuple(Target(np.array([0.4, 0.0, 0.0]), np.diag([1.0, -1.0, -1.0]),
                                       self.stated.get((key, k), name))
                                for k, name in enumerate(self.types[key])))


def test_evaluate_reports_the_fraction_of_types_stated_right():
    dataset = typed_dataset(4, seed=5, targets=2)  # 8 targets of known type
    first = dataset.images[0].tobytes()
    other = next(name for name in TYPES if name != dataset.target_types()[0][1])
    assert evaluate(Typed(dataset), dataset).type_accuracy == 1.0
    assert evaluate(Typed(dataset, {(first, 1): other}), dataset).type_accuracy == 7 / 8
    assert evaluate(Typed(dataset, {(first, 1): None}), dataset).type_accuracy == 7 / 8
    silent = {(image.tobytes(), k): None for image in dataset.images for k in range(2)}
    assert evaluate(Typed(dataset, silent), dataset).type_accuracy is None  # states no type
    unnamed = dataclasses.replace(dataset, scenes=({},) * 4)  # records that name no type
    assert evaluate(Typed(dataset), unnamed).type_accuracy is None
    assert json.loads(json.dumps(evaluate(Typed(dataset), dataset).to_json()))[
        "type_accuracy"] == 1.0


def test_train_hands_the_batch_each_targets_type_index():
    dataset = typed_dataset(6, seed=6)
    model = KqvModel.for_dataset(dataset, KqvConfig(type_head=False))
    model.scaler = model.network.scaler = LabelScaler.fit(dataset.labels[..., :3])
    seen = []

    def recording(batch):
        seen.append((batch.labels.clone(), batch.type_indices.clone()))
        return model.batch_loss(batch)

    train(model.network, recording, dataset, TrainConfig(steps=3, batch_size=4, threads=1),
          progress=False)
    by_label = {tuple(label[0, :3].tolist()): int(index[0])
                for label, index in zip(dataset.labels, dataset.target_type_indices(),
                                        strict=True)}
    for labels, indices in seen:
        assert indices.dtype == torch.int64 and indices.shape == (4, 1)
        assert [by_label[tuple(label[0, :3].tolist())] for label in labels] == \
            indices[:, 0].tolist()
    assert {index for _, indices in seen for index in indices.flatten().tolist()} <= {0, 1, 2}


def test_a_chained_report_names_its_phases():
    config = TrainConfig(steps=2)
    first = TrainReport(2, 4, 0.5, ((1, 0.6), (2, 0.5)), 1.0, 1, config)
    second = TrainReport(3, 4, 0.2, ((3, 0.2),), 2.0, 1, config)
    chained = TrainReport.chain([first, second], ("targets", "object types"))
    assert chained.phases == (("targets", 2, 0.5, 1.0), ("object types", 3, 0.2, 2.0))
    assert chained.steps == 5 and chained.losses == ((1, 0.6), (2, 0.5), (5, 0.2))
    assert json.loads(json.dumps(chained.to_json()))["phases"][1] == {
        "name": "object types", "steps": 3, "final_loss": 0.2, "wall_time_s": 2.0}
    assert TrainReport.chain([first, second]).phases == ()
    third = TrainReport(1, 4, 0.1, ((1, 0.1),), 0.5, 1, config)  # a chained report's phases
    assert [p.name for p in TrainReport.chain([chained, third], ("pose", "more")).phases] == [
        "targets", "object types", "more"]  # come with it
    with pytest.raises(InvalidInputError, match=r"names = \['targets'\] is not allowed: one per"):
        TrainReport.chain([first, second], ("targets",))


def test_the_spec_reads_the_object_types_and_compares_them_where_both_name_them():
    typed = typed_dataset(2, seed=7)
    spec = ModelSpec.from_metadata(typed.metadata)
    assert spec.object_types == TYPES
    assert ModelSpec.from_json(json.loads(json.dumps(spec.to_json()))) == spec
    old = {k: v for k, v in spec.to_json().items() if k != "object_types"}  # before the field
    assert ModelSpec.from_json(old).object_types == ()
    untyped = dataclasses.replace(typed, metadata=dataclasses.replace(typed.metadata, extra={}))
    spec.check_dataset(untyped)  # () is unknown, not other types
    dataclasses.replace(spec, object_types=()).check_dataset(typed)
    reordered = dataclasses.replace(typed, metadata=dataclasses.replace(
        typed.metadata, extra={"object_types": ["blue", "red", "green"]}))
    with pytest.raises(InvalidInputError, match=r"object_types is \('blue', 'red', 'green'\), "
                                                 r"the model's is \('red', 'green', 'blue'\)"):
        spec.check_dataset(reordered)


def test_gva_train_names_the_phases_and_evaluate_prints_the_type_accuracy(tmp_path, capsys):
    """The accuracy printed and saved is the checkpoint's own, recounted here from its answers."""
    dataset = typed_dataset(6, seed=8)
    data = save_dataset(dataset, tmp_path / "typed.gva")
    fast = ["--steps", "150", "--batch-size", "4", "--threads", "1", "--holdout", "0",
            "--no-progress"]
    assert main(["train", "--model", "kqv", "--data", str(data), "--out",
                 str(tmp_path / "kqv"), *fast]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("kqv on synthetic / multiple: 6 samples, 300 steps, final loss ")
    assert re.fullmatch(r"phases: targets 150 steps, final loss \S+; object types 150 steps, "
                        r"final loss \S+", lines[1]), lines
    assert main(["evaluate", "--model", str(tmp_path / "kqv"), "--data", str(data)]) == 0
    lines = capsys.readouterr().out.splitlines()
    saved = json.loads((tmp_path / "kqv" / "evaluation-typed.json").read_text())
    accuracy = saved["type_accuracy"]
    model = KqvModel.load(tmp_path / "kqv")
    stated = [t.object_type for p in model.predict_batch(dataset.images, dataset.conditions)
              for t in p.targets]
    truth = [scene["objects"][0]["type"] for scene in dataset.scenes]
    assert len(stated) == len(truth) == 6 and set(stated) <= set(TYPES)
    assert accuracy == pytest.approx(np.mean([s == t for s, t in zip(stated, truth, strict=True)]))
    assert accuracy >= 5 / 6  # learned from the colours: always "red" (the most common) is 4/6
    assert f"object type stated right: {100 * accuracy:.1f} % of targets" in lines


def staged(dataset, taken):
    """``dataset`` with target indices ``taken[n]`` marked as picked before image n."""
    scenes = tuple(record | {"taken": list(t)} if t else record
                   for record, t in zip(dataset.scenes, taken, strict=True))
    return dataclasses.replace(dataset, scenes=scenes)


def test_a_target_picked_before_the_image_is_absent_from_losses_types_and_scores():
    dataset = staged(typed_dataset(3, seed=8, targets=2), [(), (0,), (0, 1)])
    np.testing.assert_array_equal(dataset.target_present(),
                                  [[True, True], [False, True], [False, False]])
    assert (dataset.target_type_indices()[[1, 2, 2], [0, 0, 1]] == -1).all()
    assert (dataset.target_type_indices()[[0, 0, 1], [0, 1, 1]] >= 0).all()
    result = evaluate(Typed(dataset), dataset)
    assert result.position_errors_cm[1][0] is None and result.position_errors_cm[1][1] > 0
    errors = np.array([[e for e in row] for row in result.position_errors_cm], dtype=float)
    assert result.mean_position_error_cm == pytest.approx(np.nanmean(errors))
    assert result.per_stage_mean_position_error_cm == pytest.approx(
        (np.mean(errors[0]), errors[1, 1]))  # stage 2 has no target left: not scored
    json.dumps(result.to_json(), allow_nan=False)


def test_the_target_loss_skips_absent_targets_and_is_the_plain_mean_when_all_are_there():
    dataset = typed_dataset(4, seed=9, targets=2)
    model = KqvModel.for_dataset(dataset, KqvConfig(type_head=False))
    model.scaler = model.network.scaler = LabelScaler.fit(dataset.labels[..., :3])
    images = torch.rand(4, 3, 64, 64)
    labels = torch.from_numpy(dataset.labels)
    out = model.network(images, torch.from_numpy(dataset.conditions))
    everyone = torch.ones(4, 2, dtype=torch.bool)
    assert torch.equal(model.target_loss(out, labels, everyone), model.target_loss(out, labels))
    gone = everyone.clone()
    gone[1:, 1] = False
    garbage = labels.clone()
    garbage[1:, 1, :3] += 5.0  # where an absent target's label says it is does not count
    assert torch.allclose(model.target_loss(out, garbage, gone), model.target_loss(out, labels,
                                                                                   gone))
    assert not torch.allclose(model.target_loss(out, garbage), model.target_loss(out, labels))


def test_a_training_takes_omp_num_threads_where_set_else_every_core(monkeypatch):
    """``make test`` runs its workers at OMP_NUM_THREADS=1: two trainings at two threads each
    on two cores cost a fifth more CPU than at one (docs/decisions/speed.md)."""
    monkeypatch.delenv("OMP_NUM_THREADS", raising=False)
    assert default_threads() == available_threads()
    monkeypatch.setenv("OMP_NUM_THREADS", "1")
    assert default_threads() == 1
    monkeypatch.setenv("OMP_NUM_THREADS", "1,2")  # OpenMP's nested list: the outer level
    assert default_threads() == 1
    monkeypatch.setenv("OMP_NUM_THREADS", "4096")
    assert default_threads() == available_threads()  # never more than the cores
    monkeypatch.setenv("OMP_NUM_THREADS", "two")
    with pytest.raises(InvalidInputError, match=r"OMP_NUM_THREADS.*'two'.*integer >= 1"):
        default_threads()
