"""A served model that answers once and then falls silent costs its pick in closed loop too.

Issue 77: every re-prediction waited the full timeout (30 s) and the arm ran a plan it could no
longer confirm; the docs promise that a server's silence past its limit costs the pick.
"""

from __future__ import annotations

import threading
import time

from served_detector import serve
from user_models import FixedGrasp

from perception.remote.client import RemoteModel
from robots.yumi import YUMI
from sim.tasks.task_toml import load_task
from sim.trials.closed_loop.loop_settings import Loop, LoopSettings, Reaction
from sim.trials.records import TrialOutcome
from sim.trials.trial_runner import TrialRunner
from sim.trials.trial_scenes import trial_scene

TIMEOUT_S = 1.0


class AnswersOnce(FixedGrasp):
    """A grasp at the first prediction; then no answer for far longer than the client waits."""

    def __init__(self) -> None:
        self.calls = 0
        self.released = threading.Event()

    def predict(self, image, condition=None):
        self.calls += 1
        if self.calls > 1:
            self.released.wait(30 * TIMEOUT_S)
        return super().predict(image)


def test_a_server_silent_after_its_first_answer_costs_the_pick_within_its_timeout():
    model = AnswersOnce()
    server = serve(model)
    remote = RemoteModel(f"ws://127.0.0.1:{server.port}", timeout_s=TIMEOUT_S)
    task = load_task("single")
    started = time.perf_counter()
    try:
        with TrialRunner(task, lambda world, camera: remote, robot=YUMI,
                         loop=LoopSettings(Loop.CLOSED)) as runner:
            record = runner.run(trial_scene(task, 0, 0), 0, 0, "served")
    finally:
        model.released.set()
        server.shutdown()
    wall_s = time.perf_counter() - started
    assert record.outcome is TrialOutcome.PERCEPTION_FAILED, record.reason
    assert "no answer" in record.reason and f"within {TIMEOUT_S:g} s" in record.reason
    [pick] = record.picks
    looks = pick["repredictions"]
    assert len(looks) == 1 and looks[0]["reaction"] == Reaction.UNSEEN.value
    assert wall_s < 2 * TIMEOUT_S + 30.0, wall_s  # one silent look, not one per look
