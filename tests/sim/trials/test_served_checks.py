"""A served checkpoint is checked against the task as in-process, and tried under its sensor.

``gva serve`` announces a checkpoint's spec; ``gva trials --model ws://`` refuses one trained for
another task or sensor with the line an in-process run gives (the address in place of the
folder), and takes its sensor where the task names none.
"""

from __future__ import annotations

import dataclasses
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest

from harness.inputs.trial_settings import TrialSettings, load_trial_model
from perception.interface import ConditionKind, LabelKind
from perception.learning.learnable import ModelSpec
from perception.learning.torch_pieces import LabelScaler
from perception.models.kqv import KqvModel
from perception.remote.client import RemoteModel
from perception.remote.server import ModelServer, ServeSettings, start_server
from sim.errors import InvalidInputError
from sim.tasks.task_toml import load_task, task_to_toml
from sim.world.sensor import SensorConfig, SensorKind

YUMI_SINGLE = ModelSpec("yumi", "single", LabelKind.GRASP_POSE, 1, ConditionKind.NONE, (), 128,
                        128)  # as tests/sim/trials/test_trial_models.py's: no sensor, so ideal
D435_SPEC = dataclasses.replace(YUMI_SINGLE, sensor=SensorConfig(SensorKind.D435).to_json())


def _checkpoint(folder: Path, spec: ModelSpec) -> Path:
    """An untrained kqv checkpoint for ``spec`` (the checks read its spec, not its weights)."""
    model = KqvModel(spec, KqvModel.config_class(seed=0), LabelScaler((0.47, 0.0, 0.05), 0.1))
    return Path(model.save(folder))


@dataclasses.dataclass(frozen=True)
class Served:
    """A checkpoint folder and the address it is served on."""

    folder: Path
    url: str


@pytest.fixture(scope="module")
def served(tmp_path_factory) -> Iterator[dict[str, Served]]:
    """The ideal and the D435 single-task checkpoints, each served on a free port."""
    root = tmp_path_factory.mktemp("served")
    servers: list[ModelServer] = []
    found = {}
    for name, spec in (("ideal", YUMI_SINGLE), ("d435", D435_SPEC)):
        folder = _checkpoint(root / name, spec)
        server = start_server(ServeSettings(str(folder), 0))
        threading.Thread(target=server.serve_forever, daemon=True).start()
        servers.append(server)
        found[name] = Served(folder, f"ws://127.0.0.1:{server.port}")
    yield found
    for server in servers:
        server.shutdown()


def _refusal(model: str, task: str, **settings) -> str:
    with pytest.raises(InvalidInputError) as refused:
        load_trial_model(TrialSettings(model, task, **settings))
    return str(refused.value)


def _task_file(folder: Path, name: str, sensor: SensorConfig) -> str:
    path = folder / f"{name}.toml"
    path.write_text(task_to_toml(dataclasses.replace(load_task("single"), name=name,
                                                     camera=sensor)))
    return str(path)


def test_the_server_announces_the_spec_the_client_reads(served):
    remote = RemoteModel(served["d435"].url)
    assert remote.spec == D435_SPEC
    assert remote.announced["spec"] == D435_SPEC.to_json()


def test_a_served_checkpoint_for_another_task_is_refused_as_in_process(served):
    for checkpoint in served.values():
        here = _refusal(str(checkpoint.folder), "multiple")
        there = _refusal(checkpoint.url, "multiple")
        assert "trained for task single on scene yumi" in here
        assert there == here.replace(str(checkpoint.folder), checkpoint.url)


def test_a_served_checkpoint_under_another_sensor_is_refused_as_in_process(served, tmp_path):
    ideal_task = _task_file(tmp_path, "single-ideal", SensorConfig())
    d435_task = _task_file(tmp_path, "single-d435", SensorConfig(SensorKind.D435))
    for name, task in (("d435", ideal_task), ("ideal", d435_task)):
        checkpoint = served[name]
        here = _refusal(str(checkpoint.folder), task)
        there = _refusal(checkpoint.url, task)
        assert f"trained on images of sensor {name}" in here and "--sensor" in here
        assert there == here.replace(str(checkpoint.folder), checkpoint.url)
        load_trial_model(TrialSettings(checkpoint.url, task, allow_sensor_change=True))


def test_a_served_checkpoint_is_tried_under_its_own_sensor(served):
    for name, sensor in (("ideal", SensorConfig()), ("d435", SensorConfig(SensorKind.D435))):
        checkpoint = served[name]
        here = TrialSettings(str(checkpoint.folder), "single")  # single.toml names no sensor
        there = TrialSettings(checkpoint.url, "single")
        assert there.task_spec.camera == here.task_spec.camera == sensor
        load_trial_model(there)
