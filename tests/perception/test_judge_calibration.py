"""The judge's probability calibration: a Platt scaling of its map's chance, fitted on picks."""

from __future__ import annotations

import numpy as np
import pytest
from test_grasp_judge import _map_data, _moved

from perception.errors import InvalidInputError
from perception.judge.grasp_judge import judge_grasp
from perception.judge.grasp_tolerance import PlattScaling, ToleranceMap, logit, sigmoid
from perception.objects.catalog import SPONGE
from perception.objects.grasps import grasp_pose
from perception.poses import Pose


def test_the_fit_recovers_the_scaling_the_picks_were_drawn_from():
    rng = np.random.default_rng(0)
    rates = rng.uniform(0.05, 0.999, 20_000)
    truth = sigmoid(0.6 * logit(rates) + 1.1)  # a map pessimistic about the picks it judges
    held = rng.random(len(rates)) < truth
    scaling = PlattScaling.fit(rates, held, {"runs": "made up"})
    assert scaling.slope == pytest.approx(0.6, abs=0.05)
    assert scaling.offset == pytest.approx(1.1, abs=0.08)
    expected = sum(1 - scaling(r) for r in rates)  # misses the scaled chance expects
    assert expected == pytest.approx((~held).sum(), rel=0.02)


def test_a_calibrated_map_keeps_every_verdict_and_reports_the_scaled_chance():
    data = _map_data()
    truth = grasp_pose(SPONGE, Pose.from_xy_yaw(0.4, 0.0, 0.3))
    plain = ToleranceMap.from_json(data)
    scaled = ToleranceMap.from_json(data | {"calibration": {"slope": 0.5, "offset": 1.0}})
    for closing_m in np.linspace(0.0, 0.014, 15):
        predicted = _moved(truth, np.array([closing_m, 0.0, 0.0]), 0.0)
        before = judge_grasp(SPONGE, truth, predicted, None, plain)
        after = judge_grasp(SPONGE, truth, predicted, None, scaled)
        assert after.predicted_success == before.predicted_success
        assert after.success_rate == before.success_rate == before.probability
        assert after.to_record() == before.to_record()  # trial records keep the map's chance
        if 0.0 < before.success_rate:
            assert after.probability == pytest.approx(
                float(sigmoid(0.5 * logit(np.array(before.success_rate)) + 1.0)))
        else:
            assert after.probability == 0.0


@pytest.mark.parametrize("bad", [{"slope": 0.0, "offset": 0.0}, {"slope": -1.0, "offset": 0.0},
                                 {"slope": 1.0, "offset": float("nan")}])
def test_a_calibration_that_would_turn_the_order_round_is_refused(bad):
    with pytest.raises(InvalidInputError, match=r"calibration = .* is not allowed: a finite "
                                                 r"slope > 0 and a finite offset"):
        ToleranceMap.from_json(_map_data() | {"calibration": bad})
