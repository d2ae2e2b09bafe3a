"""studies/object_image_spans.py: the Table III objects' sizes through each robot's camera."""

from __future__ import annotations

import json

from benchmark_scripts import load_study


def test_every_object_is_sized_through_every_robots_camera(tmp_path):
    bench = load_study("object_image_spans")
    out = tmp_path / "spans.json"
    rows = bench.main(["--robots", "yumi,panda", "--out", str(out)])
    assert [(r.robot, r.object_type) for r in rows] == [
        (robot, name) for robot in ("yumi", "panda") for name in bench.OBJECTS]
    for row in rows:
        assert 0 < row.reach_min_px <= row.reach_max_px < row.span_max_px
        assert row.span_min_px <= row.span_median_px <= row.span_max_px < 128
    by = {(r.robot, r.object_type): r for r in rows}
    for robot in ("yumi", "panda"):  # the bottle, standing 17 cm tall, is the largest
        assert by[robot, "spray_bottle"].span_min_px > by[robot, "sponge"].span_max_px
    # the stand camera stands farther from the workspace (0.73 m to its target, the head
    # camera 0.66 m): every object is smaller in its image
    assert all(by["panda", n].span_median_px < by["yumi", n].span_median_px
               for n in bench.OBJECTS)
    assert json.loads(out.read_text())[0]["object_type"] == "sponge"
