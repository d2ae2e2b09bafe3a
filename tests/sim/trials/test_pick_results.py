import math

import numpy as np

from control.pick import PlanStatus
from perception.poses import Pose, rot_z
from sim.trials.pick_results import PickAttempt, PlannedPick, TrialResult, as_recorded
from sim.trials.records import TrialOutcome, TrialRecord
from sim.world.grip import DEFAULT_GRIP

DOWN = np.diag([1.0, -1.0, -1.0])
TRUTH = Pose(np.array([0.45, 0.05, 0.03]), DOWN)


def unreachable(target="mug"):
    """A pick the planner refused: it got as far as a plan status."""
    predicted = Pose(np.array([0.46, 0.05, 0.0300000004]), DOWN @ rot_z(0.1))
    planned = PlannedPick(TrialOutcome.IK_UNREACHABLE, "no arm reaches it", predicted,
                          DEFAULT_GRIP, 0.004, {"source": "depth", "points": 10},
                          PlanStatus.UNREACHABLE)
    return PickAttempt(target, TRUTH, planned, planned.outcome, planned.reason)


def test_a_pick_records_only_what_it_got_to():
    refused = PlannedPick(TrialOutcome.PERCEPTION_FAILED, "model predicted 0 targets")
    attempt = PickAttempt("sponge", TRUTH, refused, refused.outcome, refused.reason)
    assert attempt.position_error_m is None and attempt.rotation_error_rad is None
    assert attempt.to_record() == {
        "target": "sponge", "truth": {"position_m": [0.45, 0.05, 0.03],
                                      "rotation": DOWN.tolist()},
        "outcome": "perception_failed", "reason": "model predicted 0 targets"}
    assert set(unreachable().to_record()) == {
        "target", "truth", "predicted", "position_error_m", "rotation_error_rad", "grip",
        "raised_m", "obstacles", "plan_status", "outcome", "reason"}


def test_errors_are_measured_from_the_prediction_as_recorded():
    attempt = unreachable()
    kept = as_recorded(attempt.planned.predicted)
    assert kept.position[2] == 0.03  # rounded to 1e-6 m, as trials.jsonl keeps it
    assert attempt.position_error_m == float(np.linalg.norm(kept.position - TRUTH.position))
    assert math.isclose(attempt.rotation_error_rad, 0.1, abs_tol=1e-5)


def test_the_last_pick_is_the_records_top_level_and_every_pick_is_kept():
    first = PickAttempt("sponge", TRUTH, PlannedPick(), TrialOutcome.SUCCESS, "lifted", 0.08)
    result = TrialResult(TrialOutcome.IK_UNREACHABLE, "pick 2 of 3 (mug): no arm reaches it",
                         (first, unreachable()))
    record = TrialRecord(index=0, seed=0, task="multiple", model="oracle",
                         **result.record_fields())
    assert record.outcome is TrialOutcome.IK_UNREACHABLE
    assert record.reason == "pick 2 of 3 (mug): no arm reaches it"
    assert (record.target, record.plan_status, record.lift_m) == ("mug", "unreachable", None)
    assert [p["outcome"] for p in record.picks] == ["success", "ik_unreachable"]
    assert record.picks[0]["lift_m"] == 0.08
    assert TrialRecord.from_json(record.to_json()) == record


def test_a_trial_stopped_before_a_pick_ended_has_no_picks():
    fields = TrialResult(TrialOutcome.ERROR, "RuntimeError: boom").record_fields()
    assert fields == {"outcome": TrialOutcome.ERROR, "reason": "RuntimeError: boom"}
    assert TrialRecord(index=1, seed=0, task="single", model="oracle", **fields).picks == []
