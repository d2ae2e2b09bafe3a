import json

import pytest

from harness.trial_log import TrialLog
from harness.trial_summary import TrialSummary, wilson_interval
from sim.errors import RunFolderError
from sim.trials.records import TargetPick, TrialOutcome, TrialRecord


def record(index: int, outcome=TrialOutcome.SUCCESS) -> TrialRecord:
    return TrialRecord(index=index, seed=0, task="single", model="oracle", outcome=outcome,
                       reason="test", wall_time_s=1.0 + index)


def test_wilson_interval_matches_known_values():
    low, high = wilson_interval(27, 30)
    assert low == pytest.approx(0.7438, abs=1e-4)
    assert high == pytest.approx(0.9654, abs=1e-4)
    assert wilson_interval(30, 30)[1] == pytest.approx(1.0)
    assert wilson_interval(0, 30)[0] == pytest.approx(0.0)


def test_record_round_trips_through_json():
    original = record(3, TrialOutcome.GRASP_SLIPPED)
    assert TrialRecord.from_json(original.to_json()) == original


def test_log_resumes_and_keeps_finished_trials(tmp_path):
    log = TrialLog(tmp_path, {"task": "single", "seed": 0})
    log.append(record(0))
    log.append(record(1, TrialOutcome.MISSED))
    again = TrialLog(tmp_path, {"task": "single", "seed": 0})
    assert again.done(0) and again.done(1) and not again.done(2)
    summary = again.summary(2)
    assert (summary.successes, summary.n, summary.outcomes["missed"]) == (1, 2, 1)


def test_half_written_last_line_is_dropped(tmp_path):
    log = TrialLog(tmp_path, {"seed": 0})
    log.append(record(0))
    with log.path.open("a") as handle:
        handle.write(record(1).to_json()[:40])  # a crash mid-write
    again = TrialLog(tmp_path, {"seed": 0})
    assert sorted(again.records) == [0]
    again.append(record(1))
    lines = again.path.read_text().splitlines()
    assert [json.loads(line)["index"] for line in lines] == [0, 1]


def test_damaged_line_in_the_middle_is_an_error(tmp_path):
    log = TrialLog(tmp_path, {"seed": 0})
    log.append(record(0))
    log.path.write_text("not json\n" + log.path.read_text())
    with pytest.raises(RunFolderError, match="line 1 is damaged"):
        TrialLog(tmp_path, {"seed": 0})


def test_folder_of_another_run_is_refused(tmp_path):
    TrialLog(tmp_path, {"task": "single", "seed": 0})
    with pytest.raises(RunFolderError, match=r"holds a different run \(\{'seed': \(0, 1\)\}"):
        TrialLog(tmp_path, {"task": "single", "seed": 1})


def test_summary_counts_every_outcome_and_median():
    records = [record(0), record(1, TrialOutcome.IK_UNREACHABLE), record(2)]
    summary = TrialSummary.of(records)
    assert summary.outcomes["ik_unreachable"] == 1
    assert set(summary.outcomes) == {o.value for o in TrialOutcome}
    assert summary.median_wall_time_s == 2.0
    assert summary.headline().startswith("2/3 successes (95 % Wilson interval")


def test_target_picks_are_the_picks_or_the_one_pick_of_an_older_record():
    older = TrialRecord(index=0, seed=0, task="single", model="oracle",
                        outcome=TrialOutcome.MISSED, reason="test", target="mug")
    assert older.target_picks() == (TargetPick("mug", False),)
    assert record(0).target_picks() == ()  # no target: nothing to count
    newer = TrialRecord(index=0, seed=0, task="multiple", model="oracle",
                        outcome=TrialOutcome.MISSED, reason="test", target="mug",
                        picks=[{"target": "sponge", "outcome": "success"},
                               {"target": "mug", "outcome": "missed"}])
    assert newer.target_picks() == (TargetPick("sponge", True), TargetPick("mug", False))
    assert TrialSummary.of([older, newer]).per_object == {
        "mug": {"attempted": 2, "picked": 0}, "sponge": {"attempted": 1, "picked": 1}}


def test_a_trials_file_not_utf8_is_refused_naming_the_file_and_line_not_decoded_whole(tmp_path):
    # issue 63: a resumed run raised the codec's own "'utf-8' codec can't decode byte 0xff"
    log = TrialLog(tmp_path, {"seed": 0})
    log.append(record(0))
    log.append(record(1))
    text = log.path.read_bytes()
    log.path.write_bytes(b"\xff" + text)
    with pytest.raises(RunFolderError) as refused:
        TrialLog(tmp_path, {"seed": 0})
    assert str(refused.value) == (f"{log.path} line 1 is damaged: not UTF-8 text (byte 0 is "
                                  "0xff), not a line gva trials wrote")
    assert log.path.read_bytes() == b"\xff" + text  # refused, not repaired
    # a crash in the middle of a character of the last line: dropped as any partial line is
    log.path.write_bytes(text + record(2).to_json().encode()[:30] + b"\xc3")
    again = TrialLog(tmp_path, {"seed": 0})
    assert sorted(again.records) == [0, 1] and log.path.read_bytes() == text


def test_a_run_file_not_utf8_is_refused_naming_the_file(tmp_path):
    TrialLog(tmp_path, {"seed": 0})
    run = tmp_path / "run.json"
    run.write_bytes(b"\xff" + run.read_bytes())
    with pytest.raises(RunFolderError) as refused:
        TrialLog(tmp_path, {"seed": 0})
    assert str(refused.value) == (f"{run} is damaged (not UTF-8 text: byte 0 is 0xff); use "
                                  "another --out")


def test_a_run_file_damaged_is_refused_by_the_stored_identity_too(tmp_path):
    """stored_identity reads run.json as every run file is read: one reader, one message."""
    from harness.trial_log import stored_identity

    TrialLog(tmp_path, {"seed": 0})
    run = tmp_path / "run.json"
    run.write_bytes(b"\xff" + run.read_bytes())
    with pytest.raises(RunFolderError, match=r"is damaged \(not UTF-8 text: byte 0 is 0xff\); "
                                             r"use another --out"):
        stored_identity(tmp_path)
    run.write_text("{", encoding="utf-8")
    with pytest.raises(RunFolderError, match=r"run.json is damaged \(Expecting"):
        stored_identity(tmp_path)
