"""studies/check_panda_opening.py: turned sponge grasps on the Panda, per opening."""

from __future__ import annotations

import json

from benchmark_scripts import load_study


def test_a_straight_sponge_grasp_holds_at_either_opening(tmp_path):
    check = load_study("check_panda_opening")
    task = check.panda_task()
    assert task.min_spacing_m == 0.16 and task.camera.kind.value == "d435"
    scenes = check.sponge_scenes(task, 2)
    assert all(s.objects[s.targets[0]].object_type == "sponge" for s in scenes)
    out = tmp_path / "opening.json"
    outcomes = check.main(["--scenes", "1", "--openings-mm", "50,80", "--turns-deg", "0",
                           "--out", str(out)])
    assert outcomes == {"50": {"0": ["success"]}, "80": {"0": ["success"]}}
    record = json.loads(out.read_text())
    assert record["how"]["scenes"] == [scenes[0].index]
