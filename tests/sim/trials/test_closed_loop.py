"""Closed-loop picks (issue 36): re-predictions during the approach, a target moved on the way."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
from user_models import DOWN, FixedGrasp

from control.collision import CollisionReport
from control.planner import PickPlanner
from perception.camera import RgbdFrame
from perception.interface import NO_CONDITION, Prediction, Target
from perception.objects.catalog import get_object_spec
from robots import yumi
from robots.yumi import YUMI
from sim.errors import InvalidInputError
from sim.tasks.disturbance import Disturbance
from sim.tasks.task_toml import load_task
from sim.trials import trial_runner
from sim.trials.closed_loop.loop_settings import Loop, LoopSettings, Reaction, reactions
from sim.trials.closed_loop.view import ViewVerdict, hidden_share, in_plain_view, unheeded_reason
from sim.trials.oracle import OraclePerception, ViewLimitedOracle
from sim.trials.records import TrialOutcome
from sim.trials.trial_models import TRIAL_MODELS
from sim.trials.trial_runner import TrialRunner
from sim.trials.trial_scenes import trial_scene
from sim.world.head_camera import HeadCamera, camera_config
from sim.world.yumi_world import World

MOVED = Disturbance(move_m=(0.05, 0.07), turn_deg=(-30.0, 30.0))
"""Farther than a pick tolerates (a sponge is 3.5 cm wide): an open-loop pick closes on air."""


@pytest.fixture(scope="module")
def single_moved():
    return dataclasses.replace(load_task("single"), name="single-moved", disturbance=MOVED)


def run(task, loop: Loop, index: int, model=OraclePerception):
    with TrialRunner(task, model, loop=LoopSettings(loop), robot=YUMI) as runner:
        return runner.run(trial_scene(task, 0, index), index, 0, model.name)


@pytest.mark.parametrize("index", [0, 3])
def test_the_oracle_misses_a_moved_target_open_loop_and_picks_it_closed_loop(single_moved,
                                                                             index):
    blind = run(single_moved, Loop.OPEN, index)
    assert blind.outcome is TrialOutcome.MISSED, blind.reason
    [pick] = blind.picks
    assert 0.05 <= pick["disturbance"]["moved_m"] <= 0.07 + 1e-3
    assert "repredictions" not in pick  # open loop: no re-prediction
    # judged as run: the first grasp against the moved target, which it misses by the move
    assert pick["executed"]["position_error_m"] > 0.04
    assert pick["judge"]["predicted_success"] is False
    looked = run(single_moved, Loop.CLOSED, index)
    assert looked.outcome is TrialOutcome.SUCCESS, looked.reason
    [pick] = looked.picks
    assert pick["disturbance"] == blind.picks[0]["disturbance"]  # the same move, both loops
    counted = reactions(pick["repredictions"])
    assert counted["retargeted"] >= 1 and counted["unseen"] == 0
    moved_at = pick["disturbance"]["time_s"]
    retargeted = [r for r in pick["repredictions"] if r["reaction"] == "retargeted"]
    assert retargeted[0]["time_s"] >= moved_at  # it re-targets after the move, not before
    assert all(r["reaction"] == "held" for r in pick["repredictions"]
               if r["time_s"] < moved_at)
    assert pick["executed"]["position_error_m"] < 0.005  # the oracle re-read the moved target
    assert pick["judge"]["predicted_success"] is True


def test_the_view_limited_oracle_is_held_to_the_view_rule_and_the_oracle_is_not(
        single_moved, monkeypatch):
    """Issue 66's reference: the truth, heeded only where the head camera could show it."""
    asked = []

    def counted(*args, **kwargs):
        asked.append(args)
        return unheeded_reason(*args, **kwargs)

    monkeypatch.setattr("sim.trials.closed_loop.loop.unheeded_reason", counted)
    run(single_moved, Loop.CLOSED, 0)
    assert asked == []  # the oracle reads the truth, seen or not
    looked = run(single_moved, Loop.CLOSED, 0, ViewLimitedOracle)
    [pick] = looked.picks
    assert len(asked) == len(pick["repredictions"]) > 0  # every look asks the camera
    assert looked.model == "oracle-view" and TRIAL_MODELS["oracle-view"] is ViewLimitedOracle


def test_closed_loop_on_an_unmoved_target_only_holds(single_moved):
    """The oracle reads the truth, seen or not: it holds at every re-prediction."""
    looked = run(load_task("single"), Loop.CLOSED, 1)
    assert looked.outcome is TrialOutcome.SUCCESS, looked.reason
    [pick] = looked.picks
    assert pick["repredictions"] and all(
        r["reaction"] == Reaction.HELD.value for r in pick["repredictions"])
    assert "disturbance" not in pick


def test_a_move_after_the_last_re_prediction_is_seen_on_arrival(single_moved, monkeypatch):
    """Moved just before the arm rests at its pre-grasp, after the last tick: the look on
    arrival sees it, and the arm re-targets from rest."""
    drawn = trial_runner.scene_disturbance
    monkeypatch.setattr(trial_runner, "scene_disturbance", lambda *args: dataclasses.replace(
        drawn(*args), time_fraction=0.999))
    looked = run(single_moved, Loop.CLOSED, 0)
    assert looked.outcome is TrialOutcome.SUCCESS, looked.reason
    [pick] = looked.picks
    after = [r for r in pick["repredictions"] if r["time_s"] >= pick["disturbance"]["time_s"]]
    assert after[0]["reaction"] == "retargeted"
    assert pick["executed"]["position_error_m"] < 0.005


def test_the_share_of_a_footprint_the_arm_hides():
    """A footprint is hidden where the robot's pixels or the image's edge cover it."""
    camera = camera_config(YUMI).pinhole
    size = (camera.height_px, camera.width_px)
    rgb, depth = np.zeros((*size, 3), np.uint8), np.ones(size, np.float32)
    center = np.array([0.45, 0.0, 0.03])
    u, v = np.round(camera.project(center[None])[0]).astype(int)
    clear = np.zeros(size, bool)
    assert hidden_share(RgbdFrame(rgb, depth, camera), center, 0.045) == 0.0  # no mask: at rest
    assert hidden_share(RgbdFrame(rgb, depth, camera, robot_mask=clear), center, 0.045) == 0.0
    left = clear.copy()
    left[:, :u] = True  # the arm over the left half of the view
    share = hidden_share(RgbdFrame(rgb, depth, camera, robot_mask=left), center, 0.045)
    assert 0.35 < share < 0.65
    spot = clear.copy()
    spot[v, u] = True  # one pixel, on the footprint's centre
    assert hidden_share(RgbdFrame(rgb, depth, camera, robot_mask=spot), center, 0.045) > 0.0
    assert hidden_share(RgbdFrame(rgb, depth, camera, robot_mask=clear),
                        np.array([0.45, 2.0, 0.03]), 0.045) == 1.0  # out of view


def test_a_grasp_in_plain_view_has_its_footprint_seen_and_something_standing_there():
    """Where the arm hides the target followed, a grasp named in plain view over an object is
    heeded (a target moved out from under the arm); one on bare table or behind the arm not."""
    with World(robot=YUMI) as world:
        world.reset_scene()
        world.add_object(get_object_spec("spray_bottle"), (0.45, 0.1), 0.0)
        camera = HeadCamera(camera_config(YUMI))
        frame = camera.render_rgbd(world.client, self_body=world.robot.body_id)
    bottle, bare = np.array([0.45, 0.1, 0.08]), np.array([0.45, -0.1, 0.08])
    assert frame.robot_mask is not None
    assert in_plain_view(frame, bottle, 0.045)
    assert not in_plain_view(frame, bare, 0.045)  # nothing stands there
    u, v = np.round(frame.camera.project(bottle[None])[0]).astype(int)
    hidden = frame.robot_mask.copy()
    hidden[v, u] = True  # the arm over the bottle
    assert not in_plain_view(dataclasses.replace(frame, robot_mask=hidden), bottle, 0.045)
    # the loop's verdict: the target followed at the bare spot, the arm over it
    u, v = np.round(frame.camera.project(bare[None])[0]).astype(int)
    over_bare = frame.robot_mask.copy()
    over_bare[v - 2:v + 3, u - 2:u + 3] = True
    arm_over = dataclasses.replace(frame, robot_mask=over_bare)
    assert unheeded_reason(frame, bare, bottle, 0.045, None, 0.01) == ViewVerdict(None)  # seen
    verdict = unheeded_reason(arm_over, bare, bottle, 0.045, None, 0.01)
    once = verdict.unconfirmed_m
    assert verdict.unheeded is not None
    assert verdict.unheeded.endswith("the next look must confirm it")
    assert once is not None and np.array_equal(once, bottle)
    assert unheeded_reason(arm_over, bare, bottle + 0.004, 0.045, once, 0.01) == ViewVerdict(None)
    step = np.array([0.0, 0.05, 0.0])
    unheeded = unheeded_reason(arm_over, bare, bottle + step, 0.045, once, 0.01).unheeded
    assert unheeded is not None and unheeded.startswith("the arm hides ")  # not the one seen
    verdict = unheeded_reason(arm_over, bare, bare + 0.4 * step, 0.045, None, 0.01)
    assert verdict.unheeded is not None and "nothing stands in plain view" in verdict.unheeded
    assert verdict.unconfirmed_m is None


def test_loop_settings_are_checked():
    with pytest.raises(InvalidInputError, match=r"replan_hz = 0.0 is not allowed: a rate in "
                                                 r"\(0, 60\] Hz"):
        LoopSettings(Loop.CLOSED, replan_hz=0.0)
    with pytest.raises(InvalidInputError, match=r"move_threshold_m = -0.01 .* >= 0"):
        LoopSettings(move_threshold_m=-0.01)
    with pytest.raises(InvalidInputError, match=r"footprint_radius_m = nan .* >= 0"):
        LoopSettings(footprint_radius_m=float("nan"))
    with pytest.raises(InvalidInputError, match=r"loop = 'closed' is not allowed: open or "
                                                 r"closed"):
        LoopSettings("closed")  # type: ignore[arg-type]
    assert LoopSettings().to_json() == {"loop": "open"}
    assert LoopSettings(Loop.CLOSED).to_json()["replan_hz"] == 10.0


def test_gva_trials_closes_the_loop_and_records_it(tmp_path):
    from gva_cli import gva

    status, stdout, err = gva("trials", "--task", "single", "--n", 1, "--out", tmp_path / "r",
                              "--loop", "closed", "--replan-hz", 5, "--workers", 1,
                              "--no-progress")
    assert status == 0, stdout + err
    run = json.loads((tmp_path / "r" / "run.json").read_text())
    assert run["loop"] == LoopSettings(Loop.CLOSED, replan_hz=5.0).to_json()
    [record] = [json.loads(line) for line in (tmp_path / "r" / "trials.jsonl").open()]
    assert len(record["picks"][0]["repredictions"]) >= 3  # 5 Hz over a ~1.5 s approach
    status, _, err = gva("trials", "--task", "single", "--n", 1, "--out", tmp_path / "s",
                         "--replan-hz", 5)
    assert status == 2
    assert "--replan-hz = 5.0 is not allowed: only with --loop closed" in err
    assert not (tmp_path / "s").exists()


class _Later(FixedGrasp):
    """The fixed grasp at the first prediction; what ``later`` says at every one after it."""

    calls = 0

    def predict(self, image, condition=NO_CONDITION):
        type(self).calls += 1
        first = super().predict(image, condition)
        return first if type(self).calls == 1 else self.later(first)

    def later(self, first):
        return first


class _RaisesLater(_Later):
    def later(self, first):
        raise RuntimeError("the detector lost the target")


class _Unreachable(_Later):
    def later(self, first):  # a grasp 1.5 m away: no arm reaches it
        return Prediction((Target(np.array([1.5, 0.0, 0.03]), DOWN.copy()),))


def run_closed(model: type[_Later]):
    """A closed-loop trial of ``single`` scene 0 with ``model``; the record and the runner's TCP."""
    model.calls = 0
    task = load_task("single")
    with TrialRunner(task, lambda world, camera: model(),
                     loop=LoopSettings(Loop.CLOSED), robot=YUMI) as runner:
        record = runner.run(trial_scene(task, 0, 0), 0, 0, "test")
        arm = record.picks[0].get("arm", "r")
        return record, runner.world.robot.link_pose(yumi.TCP_FRAME[arm]).position


@pytest.mark.parametrize(("model", "reaction"), [(_RaisesLater, Reaction.UNSEEN),
                                                 (_Unreachable, Reaction.KEPT)])
def test_a_re_prediction_the_arm_cannot_follow_keeps_the_plan_and_says_why(model, reaction):
    record, _ = run_closed(model)
    [pick] = record.picks
    assert pick["repredictions"]
    seen = {r["reaction"] for r in pick["repredictions"]}
    if reaction is Reaction.KEPT:  # a grasp named, not heeded where the arm hides the target
        assert seen == {reaction.value, Reaction.HIDDEN.value}
    else:  # no grasp named: nothing to heed
        assert seen == {reaction.value}
    hidden = [r for r in pick["repredictions"] if r["reaction"] == Reaction.HIDDEN.value]
    assert all(r["reason"].startswith("the arm hides ") for r in hidden)
    assert all(r["reason"] for r in pick["repredictions"])
    assert "arm" in pick  # the first plan was followed to the end
    assert record.outcome is not TrialOutcome.ERROR
    if reaction is Reaction.KEPT:  # the arm does not descend to a grasp it knows is stale
        assert record.outcome is TrialOutcome.IK_UNREACHABLE
        assert record.reason.startswith("approach: the grasp moved and no re-plan reached it: ")


def test_a_failed_re_plan_whose_path_ahead_is_blocked_brakes_the_arm(monkeypatch):
    """No re-plan, and the plan followed runs into what the frame shows: the arm brakes where
    it is (never reaching the pre-grasp) and the pick ends with the re-plan's outcome."""
    blocked = CollisionReport(True, (("gripper_finger", "depth"),), 40)
    monkeypatch.setattr(PickPlanner, "check_ahead", lambda *args: blocked)
    record, tcp = run_closed(_Unreachable)
    [pick] = record.picks
    first = pick["repredictions"][0]
    assert first["reaction"] == Reaction.STOPPED.value
    assert first["reason"].startswith("the plan followed: collision at sample 40: "
                                      "gripper_finger vs depth; arm ")
    assert record.outcome is TrialOutcome.IK_UNREACHABLE
    assert record.reason.startswith("approach: the grasp moved and no re-plan reached it: ")
    assert tcp[2] > 0.15  # braked high above the table, never descended


class _Wandering(OraclePerception):
    """The oracle's grasp, 2 cm to one side and then the other at each look: never settles."""

    looks = 0

    def predict(self, image, condition=NO_CONDITION):
        told = super().predict(image, condition)
        self.looks += 1
        shift = np.array([0.0, 0.02 if self.looks % 2 else -0.02, 0.0])
        return dataclasses.replace(told, targets=tuple(
            dataclasses.replace(t, position_m=t.position_m + shift) for t in told.targets))


def test_an_approach_that_never_settles_stops_looking_and_the_trial_ends(monkeypatch):
    """A grasp that moves beyond the threshold at every look re-targets at every look; past
    MAX_APPROACH_S the loop stops looking, says so, and the pick runs its last plan."""
    monkeypatch.setattr("sim.trials.closed_loop.loop.MAX_APPROACH_S", 1.0)
    task = load_task("single")
    with TrialRunner(task, _Wandering, loop=LoopSettings(Loop.CLOSED), robot=YUMI) as runner:
        record = runner.run(trial_scene(task, 0, 1), 1, 0, "wandering")
    [pick] = record.picks
    looks = pick["repredictions"]
    assert reactions(looks)["retargeted"] >= 5  # it kept re-targeting until the limit
    timed_out = [i for i, r in enumerate(looks) if r["reaction"] == Reaction.TIMED_OUT.value]
    assert len(timed_out) == 1 and timed_out[0] == len(looks) - 1  # no look after it
    assert looks[-1]["time_s"] >= 1.0 and "passed 1 s" in looks[-1]["reason"]
    assert record.outcome is not TrialOutcome.ERROR, record.reason
