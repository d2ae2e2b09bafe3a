"""``gva serve`` serves a checkpoint of every registered model, and ``gva evaluate`` a served one.

Each model is trained two steps on a tiny synthetic dataset (the test proves the paths, not
that a model learns), served from its checkpoint folder in a thread, and asked once: the served
grasp is the one the checkpoint predicts in-process. No pick trials: they are the model
matrix's (tests/experiments/test_model_matrix.py), marked slow.
"""

from __future__ import annotations

import json
import threading
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from gva_cli import gva
from user_models import CAMERA, synthetic_dataset

from perception.interface import LabelKind, RgbdFrame
from perception.learning.dataset_file import save_dataset
from perception.learning.train import TrainConfig
from perception.registry import MODELS, PRESETS, load_model, model_class, new_model
from perception.remote.client import RemoteModel
from perception.remote.server import ModelServer, ServeSettings, start_server


def registered_models() -> tuple[str, ...]:
    """Each preset, and each registered model no preset stands for at its defaults (as
    tests/experiments/test_model_matrix.py's ``registered_models``)."""
    def at_defaults(base: str, settings: Mapping[str, Any]) -> bool:
        config = model_class(base).config_class()
        return all(getattr(config, key) == value for key, value in settings.items())

    same = {base for base, settings in PRESETS.values() if at_defaults(base, settings)}
    return (*(name for name in MODELS if name not in same), *PRESETS)


@pytest.fixture(scope="module")
def dataset():
    return synthetic_dataset(2, kind=LabelKind.GRASP_POSE, seed=1, camera=CAMERA)


@pytest.fixture(scope="module")
def checkpoints(dataset, tmp_path_factory) -> dict[str, Path]:
    """A two-step checkpoint of every registered model."""
    root, folders = tmp_path_factory.mktemp("served-models"), {}
    for name in registered_models():
        model = new_model(name, dataset, seed=0)
        model.fit(dataset, TrainConfig(steps=2, batch_size=2, threads=1), progress=False)
        folders[name] = Path(model.save(root / name))
    return folders


def _serving(folder: Path) -> ModelServer:
    server = start_server(ServeSettings(str(folder), 0))
    threading.Thread(target=server.serve_forever, daemon=True).start()
    return server


@pytest.fixture
def served_kqv(checkpoints) -> Iterator[str]:
    server = _serving(checkpoints["kqv"])
    yield f"ws://127.0.0.1:{server.port}"
    server.shutdown()


@pytest.mark.parametrize("name", registered_models())
def test_every_registered_model_is_served_as_it_predicts_in_process(name, checkpoints,
                                                                      dataset):
    frame = RgbdFrame(dataset.images[0], np.full((64, 64), 0.6, np.float32), CAMERA)
    condition = dataset.condition(0)
    here = load_model(checkpoints[name]).predict_frame(frame, condition)
    server = _serving(checkpoints[name])
    try:
        remote = RemoteModel(f"ws://127.0.0.1:{server.port}")
        there = remote.predict_frame(frame, condition)
        remote.close()
    finally:
        server.shutdown()
    assert remote.announced["name"] == load_model(checkpoints[name]).name
    assert remote.spec is not None and remote.spec.task == dataset.metadata.task
    assert len(here.targets) == len(there.targets) == 1
    for a, b in zip(here.targets, there.targets, strict=True):
        assert np.array_equal(a.position_m, b.position_m)
        assert np.array_equal(a.rotation, b.rotation) and a.object_type == b.object_type
    assert np.array_equal(here.attention_px, there.attention_px)


def test_evaluate_scores_a_served_model_as_its_checkpoint_and_records_what_it_announced(
        served_kqv, checkpoints, dataset, tmp_path):
    data = save_dataset(dataset, tmp_path / "test.npz")
    status, _, err = gva("evaluate", "--model", checkpoints["kqv"], "--data", data, "--out",
                         tmp_path / "here.json")
    assert status == 0, err
    status, out, err = gva("evaluate", "--model", served_kqv, "--data", data, "--out",
                           tmp_path / "there.json")
    assert status == 0, err
    assert "evaluation:" in out
    here = json.loads((tmp_path / "here.json").read_text())
    there = json.loads((tmp_path / "there.json").read_text())
    assert there["served"] == served_kqv and "checkpoint" not in there
    assert there["announced"]["name"] == "kqv"
    assert there["weights_sha256"] == here["weights_sha256"]  # as the server announced it
    assert there["samples"] == here["samples"] == 2
    # one frame at a time there, a batch here: the same sums to float32's rounding
    assert there["mean_position_error_cm"] == pytest.approx(here["mean_position_error_cm"],
                                                            rel=1e-5)
    for key in ("position_errors_cm", "angle_errors_deg"):
        assert np.allclose(there[key], here[key], rtol=1e-5), key


def test_evaluate_of_a_served_model_needs_out_and_a_server(dataset, tmp_path):
    data = save_dataset(dataset, tmp_path / "test.npz")
    status, _, err = gva("evaluate", "--model", "ws://127.0.0.1:9", "--data", data)
    assert status == 2 and "--out" in err and len(err.strip().splitlines()) == 1
    status, _, err = gva("evaluate", "--model", "ws://127.0.0.1:9", "--data", data, "--out",
                         tmp_path / "x.json")
    assert status == 2 and "unreachable" in err and len(err.strip().splitlines()) == 1
