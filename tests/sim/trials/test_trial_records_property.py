"""Generated trial records thrown at what reads them: ``gva judge`` and a resumed run (issue 63).

A valid run's ``trials.jsonl`` mutated (a key dropped, a value of another type, NaN and inf, a
number past 64 bits, a line cut, bytes that are not UTF-8, a line of junk): reading it either
gives records and a judgement, or is refused by an ``InvalidInputError`` or ``RunFolderError``
in one line naming the file. Never another exception, never a "+nan" in a judgement.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from harness.judging import judge_run
from perception.objects.catalog import SPONGE
from perception.objects.grasps import grasp_pose
from perception.poses import Pose
from sim.errors import InvalidInputError, RunFolderError
from sim.trials.pick_results import pose_json
from sim.trials.records import TrialOutcome, TrialRecord, read_trial_records

TRUTH = grasp_pose(SPONGE, Pose.from_xy_yaw(0.45, 0.0, 0.0))


def _record(index: int) -> dict[str, Any]:
    pick = {"target": "sponge", "truth": pose_json(TRUTH.position, TRUTH.rotation),
            "predicted": pose_json(TRUTH.position + 0.002 * index, TRUTH.rotation),
            "outcome": "success", "reason": "held"}
    record = TrialRecord(index=index, seed=0, task="single", model="kqv",
                         outcome=TrialOutcome.SUCCESS, reason="held",
                         objects=[{"type": "sponge", "position_xy_m": [0.45, 0.0],
                                   "yaw_rad": 0.0, "distractor": False}],
                         target="sponge", truth=pick["truth"], predicted=pick["predicted"],
                         picks=[pick])
    return json.loads(record.to_json())


_ODD = st.one_of(st.sampled_from([None, True, -1, 2**64, 10**30, math.nan, math.inf, "", "x",
                                  [], {}, [math.nan, 0, 0], [1, 2]]),
                 st.integers(), st.floats(), st.text(max_size=6))


@st.composite
def trial_files(draw: st.DrawFn) -> bytes:
    """Three records' lines, each maybe mutated; then maybe a junk or cut line."""
    lines = []
    for index in range(3):
        record = _record(index)
        for _ in range(draw(st.integers(0, 2))):
            path = draw(st.sampled_from([("index",), ("outcome",), ("objects",), ("picks",),
                                         ("seed",), ("predicted", "position_m"),
                                         ("truth", "rotation"), ("picks", 0, "predicted"),
                                         ("picks", 0, "outcome"), ("target",)]))
            holder: Any = record
            for step in path[:-1]:  # an earlier mutation may have removed or replaced it
                if isinstance(holder, dict):
                    holder = holder.get(step)
                elif isinstance(holder, list) and isinstance(step, int) and step < len(holder):
                    holder = holder[step]
                else:
                    holder = None
            if isinstance(holder, dict) or (isinstance(holder, list) and holder):
                if draw(st.booleans()) and isinstance(holder, dict):
                    holder.pop(path[-1], None)
                else:
                    holder[path[-1]] = draw(_ODD)
        lines.append(json.dumps(record, allow_nan=True).encode())
    tail = draw(st.sampled_from(["none", "none", "junk", "cut", "bytes"]))
    if tail == "junk":
        lines.insert(draw(st.integers(0, 3)), draw(st.text(max_size=20)).encode())
    elif tail == "cut":
        lines[-1] = lines[-1][:draw(st.integers(0, len(lines[-1])))]
    elif tail == "bytes":
        lines.insert(draw(st.integers(0, 3)), draw(st.binary(min_size=1, max_size=12)))
    return b"\n".join(lines) + b"\n"


@settings(max_examples=200, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(data=trial_files())
def test_any_trials_file_is_judged_or_refused_in_one_line(tmp_path_factory, data):
    run = Path(tmp_path_factory.mktemp("run"))
    path = run / "trials.jsonl"
    path.write_bytes(data)
    try:
        read_trial_records(path)
        judgement = judge_run(run)
    except (InvalidInputError, RunFolderError) as error:
        message = str(error)
        assert "\n" not in message and "trials.jsonl" in message, message
        event(f"refused: {type(error).__name__}")
        return
    assert "nan" not in json.dumps(judgement.to_json(), allow_nan=True).lower()
    event("judged")
