"""Fixtures of the tests of examples/plugins' detectors: the plug-in built as --model finds it.

A test module names its detector in ``PLUGIN`` (``"module:Class"`` of examples/plugins); the
fixtures build it once per module and set up its scenes in one runner.
"""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from plugin_detectors import PLUGINS

from perception.interface import PerceptionModel
from perception.plugins import build_plugin
from robots.yumi import YUMI
from sim.tasks.task_toml import load_task
from sim.trials.trial_runner import TrialRunner


@pytest.fixture(scope="module")
def detector(request: pytest.FixtureRequest) -> Iterator[PerceptionModel]:
    """The test module's ``PLUGIN``, built from examples/plugins as ``--model`` finds it."""
    with pytest.MonkeyPatch.context() as patch:
        patch.syspath_prepend(str(PLUGINS))
        yield build_plugin(request.module.PLUGIN)


@pytest.fixture(scope="module")
def runner(detector: PerceptionModel) -> Iterator[TrialRunner]:
    """A YuMi runner with ``detector`` in the loop: it sets up and renders any task's scenes
    (they share the light)."""
    with TrialRunner(load_task("single"), lambda world, camera: detector, robot=YUMI) as runner:
        yield runner
