"""What the tests of examples/plugins' detectors share: where they live, what they may import,
and the check that a detector grasps a task's targets (fixtures: tests/examples/conftest.py)."""

from __future__ import annotations

import ast
import sys

import numpy as np
from served_detector import PLUGINS

from perception.interface import PerceptionModel
from sim.tasks.scene_sampling import SeedStream, sample_scene
from sim.tasks.scene_specs import YUMI_SCENE
from sim.tasks.task_toml import load_task
from sim.trials.pick_results import grasp_angle_rad
from sim.trials.trial_runner import TrialRunner

__all__ = ["ALLOWED_IMPORTS", "PLUGINS", "assert_grasps_every_target", "imports_beyond_the_rule"]
ALLOWED_IMPORTS = frozenset({"perception", "numpy", "table_objects"}) | sys.stdlib_module_names
"""table_objects: what the folder's two detectors share (examples/plugins/table_objects.py)."""


def imports_beyond_the_rule(module: str) -> set[str]:
    """What ``module`` (a file of examples/plugins) and the shared ``table_objects`` import that
    is neither ``perception``, numpy nor the standard library; a relative import fails."""
    imported = set()
    for name in (module, "table_objects.py"):
        for node in ast.walk(ast.parse((PLUGINS / name).read_text())):
            if isinstance(node, ast.Import):
                imported |= {alias.name for alias in node.names}
            elif isinstance(node, ast.ImportFrom):
                assert node.level == 0, f"{name}: a relative import on line {node.lineno}"
                imported.add(node.module)
    assert "perception.interface" in imported
    return {name for name in imported if name.partition(".")[0] not in ALLOWED_IMPORTS}


def assert_grasps_every_target(runner: TrialRunner, detector: PerceptionModel, task_name: str,
                               indices: tuple[int, ...], position_tolerance_m: float,
                               angle_tolerance_rad: float) -> None:
    """``detector`` names each target of test scenes ``indices`` of ``task_name`` (seed 0), of
    its type, its grasp within the tolerances of the truth's: a detector's whole promise."""
    task = load_task(task_name)
    for index in indices:
        scene = sample_scene(task, YUMI_SCENE, 0, SeedStream.TEST, index)
        bodies = runner.setup(scene)
        prediction = detector.predict_frame(runner.sense(), scene.condition)
        assert len(prediction.targets) == len(scene.targets)
        assert prediction.attention_px.shape == (len(scene.targets), 2)
        for target, number in zip(prediction.targets, scene.targets, strict=True):
            truth = runner.truth(bodies[number])
            assert target.object_type == scene.objects[number].object_type
            assert np.linalg.norm(target.position_m - truth.position) < position_tolerance_m
            assert grasp_angle_rad(truth.rotation, target.rotation) < angle_tolerance_rad
