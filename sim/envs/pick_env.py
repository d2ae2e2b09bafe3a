"""``gva/Pick-v0``: a gva task as a Gymnasium environment, one ``step`` per pick.

For labs whose policy code, RL library or ``lerobot-eval`` drives simulators through Gymnasium:
an episode is one trial of a task, the observation is what a gva model is given (the head
camera's RGB-D frame and calibration, the robot's joints, the condition), the action is a grasp,
and the environment plans and runs it through the same code path as ``gva trials``
(:meth:`sim.trials.trial_runner.TrialRunner.attempt`), so a grasp gets the outcome it gets in a
trial.

Episodes are paired, whatever ran before: ``reset(seed=s, options={"index": i})`` puts test
scene ``i`` of seed ``s`` on the table, the scene of trial ``i`` of a ``gva trials --seed s``
run, and the physics starts afresh for each. Without ``options`` a reset takes the next index
(``first_index``, then every ``index_step``-th): give the envs of a vector env disjoint indices
(``first_index=k, index_step=N``) and the same seed (``reset(seed=[s] * N)``).
"""

from __future__ import annotations

import math
import string
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces

from perception.camera import PinholeCamera
from perception.checks import check_prediction
from perception.errors import InvalidPredictionError
from perception.interface import (
    MAX_SENTENCE_CHARS,
    PICTURE_PX,
    ConditionKind,
    LabelKind,
    Prediction,
    Target,
    condition_size,
)
from robots import DEFAULT_ROBOT
from sim.errors import InvalidInputError
from sim.tasks.scene_specs import YUMI_SCENE
from sim.tasks.task_in_scene import condition_choices
from sim.tasks.task_sensor import seen_through
from sim.tasks.task_spec import TaskSpec, spaced_for
from sim.tasks.task_toml import load_task
from sim.trials.execution import ExecutionSettings
from sim.trials.pick_results import PickAttempt, Sighting, trial_result
from sim.trials.records import TrialOutcome
from sim.trials.trial_runner import TrialRunner
from sim.trials.trial_scenes import trial_scene
from sim.world.robot_choice import resolve_robot
from sim.world.sensor import SensorKind

WORKSPACE_BOUND_M = 1.0
"""Grasp positions the action space holds: within this of the robot base on each axis [m]."""

ROTATION_6D_MOST = 1e100
"""Largest magnitude of a ``rotation_6d`` entry: only the axes' directions count, and past
about 1e154 an axis's squared length overflows float64 (its rotation would come out zero)."""

_KINDS = tuple(ConditionKind)
_ACTION_KEYS = ("position_m", "rotation_6d", "object_type", "opening_m")


class PickEnv(gymnasium.Env[dict[str, Any], dict[str, Any]]):
    """A gva task's trials, one pick per ``step``.

    Args:
        task: A built-in task's name or a task file's path (what ``gva trials --task`` takes),
            or a :class:`~sim.tasks.task_spec.TaskSpec`.
        render_mode: ``"rgb_array"`` (the head camera's image) or None.
        first_index: The test-scene index of the first episode after a seeded reset.
        index_step: How far each unseeded reset moves the index (N in a vector env of N).
        execution: How picks are executed and judged; the trials' default when None.
        robot: The robot that picks (one of :data:`robots.ROBOT_NAMES`), seen through its
            workcell's camera, its task's objects spaced for its hand, as ``gva trials
            --robot`` runs it.
        sensor: What the head camera renders through, ``"d435"`` or ``"ideal"`` (or a
            :class:`~sim.world.sensor.SensorKind`), replacing the task's ``[camera] sensor``
            as ``gva trials --sensor`` does; None: the task's, else the D435
            (:mod:`sim.tasks.task_sensor`). :attr:`task` names the one it renders through.

    Observation (a dict): ``rgb`` (H, W, 3) uint8; ``depth_m`` (H, W) float32, depth along the
    optical axis [m], 0 or inf where none; ``K`` (3, 3) intrinsics (OpenCV's convention);
    ``T_world_camera`` (4, 4) the camera's optical frame in the world; ``joints`` the robot's
    joint positions [rad, m] in :attr:`joint_names` order; ``condition``: ``kind`` (index into
    :class:`~perception.interface.ConditionKind`), and where the task has them ``vector`` (the
    one-hot, sentence embedding or picture a learned Query reads), ``sentence``, ``picture``.

    Action (a dict): ``position_m`` (3,), the TCP at the grasp in the world [m];
    ``rotation_6d`` (6,), the TCP's x (closing) and y axes in the world, one after the other
    (Zhou et al.'s 6-D rotation, made orthonormal by Gram-Schmidt); optional ``object_type``
    (0: not stated, k: :attr:`object_types` [k - 1]), which sets the grip as a model's stated
    type does, and ``opening_m`` (1,) (0: not stated), the finger gap to approach with [m].

    Reward 1 for each target picked; ``terminated`` once every target is picked or a pick
    failed; ``info`` says the outcome, its reason, the grasp's errors and the grasp judge's
    verdict, and at the end the trial's outcome as ``gva trials`` records it.

    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 1}  # noqa: RUF012 (Gymnasium's)

    def __init__(self, task: str | Path | TaskSpec = "single", render_mode: str | None = None,
                 first_index: int = 0, index_step: int = 1,
                 execution: ExecutionSettings | None = None, robot: str = DEFAULT_ROBOT,
                 sensor: str | SensorKind | None = None) -> None:
        if render_mode not in (None, *self.metadata["render_modes"]):
            raise InvalidInputError("render_mode", render_mode, "None or 'rgb_array'")
        for name, value, least in (("first_index", first_index, 0), ("index_step", index_step, 1)):
            if isinstance(value, bool) or not isinstance(value, int) or value < least:
                raise InvalidInputError(name, value, f"an integer >= {least}")
        description = resolve_robot(robot)
        loaded = task if isinstance(task, TaskSpec) else load_task(task)
        self.task = spaced_for(seen_through(loaded, sensor), description.neighbour_spacing_m)
        self.render_mode = render_mode
        self.first_index, self.index_step = first_index, index_step
        self._runner = TrialRunner(self.task, execution=execution,
                                   robot=description)  # its model: the oracle
        self.description = description  # the robot that picks
        self.max_opening_m = description.max_opening_m
        self.object_types: tuple[str, ...] = YUMI_SCENE.object_types
        self.joint_names: tuple[str, ...] = tuple(self._runner.world.robot.joint_names)
        self.observation_space = self._observation_space()
        self.action_space = spaces.Dict({
            "position_m": spaces.Box(-WORKSPACE_BOUND_M, WORKSPACE_BOUND_M, (3,), np.float64),
            "rotation_6d": spaces.Box(-1.0, 1.0, (6,), np.float64),
            "object_type": spaces.Discrete(len(self.object_types) + 1),
            "opening_m": spaces.Box(0.0, self.max_opening_m, (1,), np.float64),
        })
        self._seed, self._next_index = 0, first_index
        self._scene: Any = None
        self._targets: list[int] = []
        self._picks: list[PickAttempt] = []
        self._sighting: Sighting | None = None

    def _observation_space(self) -> spaces.Dict:
        camera = self._runner.mounted_camera.config
        h, w = camera.height_px, camera.width_px
        kind = self.task.model_condition
        condition: dict[str, spaces.Space[Any]] = {"kind": spaces.Discrete(len(_KINDS))}
        size = condition_size(kind, condition_choices(self.task, YUMI_SCENE))
        if size:
            condition["vector"] = spaces.Box(-1.0, 1.0, (size,), np.float32)  # unit-norm or [0, 1]
        if kind is ConditionKind.TEXT:
            phrases = self.task.phrasings
            seen = "" if phrases is None else "".join(
                p for table in (phrases.train, phrases.test) for _, ps in table for p in ps)
            charset = "".join(sorted(set(string.printable) | set(seen)))
            condition["sentence"] = spaces.Text(MAX_SENTENCE_CHARS, min_length=1, charset=charset)
        if kind is ConditionKind.IMAGE:
            condition["picture"] = spaces.Box(0, 255, (PICTURE_PX, PICTURE_PX, 3), np.uint8)
        self._condition_keys = frozenset(condition)
        return spaces.Dict({
            "rgb": spaces.Box(0, 255, (h, w, 3), np.uint8),
            "depth_m": spaces.Box(0.0, np.inf, (h, w), np.float32),
            "K": spaces.Box(0.0, 1e3 * max(h, w), (3, 3), np.float64),  # fields of view >= 0.1°
            "T_world_camera": spaces.Box(-WORKSPACE_BOUND_M * 10, WORKSPACE_BOUND_M * 10, (4, 4),
                                         np.float64),
            "joints": spaces.Box(-2 * np.pi, 2 * np.pi, (len(self.joint_names),), np.float64),
            "condition": spaces.Dict(condition),
        })

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[dict[str, Any], dict[str, Any]]:
        """Puts test scene ``options["index"]`` (else the next index) of ``seed`` on the table.

        Before any seed is given the scenes are seed 0's, as ``gva trials``' default. A reset
        refused (a bad seed or option) changes nothing: the episode before it goes on.
        """
        if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int | np.integer)
                                 or seed < 0):
            raise InvalidInputError("seed", seed, "None or an integer >= 0")
        options = dict(options or {})
        unknown = sorted(set(options) - {"index"})
        if unknown:
            raise InvalidInputError("options", unknown, "only 'index' (a test-scene index)")
        index = options.get("index", self._next_index if seed is None else self.first_index)
        if isinstance(index, bool) or not isinstance(index, int | np.integer) or index < 0:
            raise InvalidInputError("options['index']", index, "an integer >= 0")
        super().reset(seed=seed)  # checked first: a refused reset leaves every state as it was
        if seed is not None:
            self._seed = int(seed)
        self._next_index = int(index) + self.index_step
        self._scene = trial_scene(self.task, self._seed, int(index))
        bodies = self._runner.setup(self._scene)
        self._targets = [bodies[i] for i in self._scene.targets]
        self._picks = []
        self._sighting = self._runner.sight(self._targets[0])
        return self._observation(), {"seed": self._seed, "index": int(index),
                                     "targets": len(self._targets)}

    def step(self, action: dict[str, Any]
             ) -> tuple[dict[str, Any], float, bool, bool, dict[str, Any]]:
        """Plans and runs the grasp ``action`` on the current target, as a trial would."""
        if self._sighting is None:
            raise gymnasium.error.ResetNeeded("call reset() before step(), and again after an "
                                              "episode ends")
        sighting, number, total = self._sighting, len(self._picks), len(self._targets)
        attempt = self._runner.attempt(sighting, Prediction((self._target(action),)), 0, 1)
        self._picks.append(attempt)
        more = self._runner.next_pick(attempt, sighting.body, number, total)
        info = {"seed": self._seed, "index": self._scene.index, "pick": number,
                "target": attempt.target, "outcome": attempt.outcome.value,
                "reason": attempt.reason, "position_error_m": attempt.position_error_m,
                "rotation_error_rad": attempt.rotation_error_rad,
                "judge": None if attempt.verdict is None else attempt.verdict.to_record()}
        if more:
            self._sighting = self._runner.sight(self._targets[number + 1])
        else:
            result = trial_result(self._picks, total)
            info |= {"trial_outcome": result.outcome.value, "trial_reason": result.reason}
            self._sighting = None
        reward = float(attempt.outcome is TrialOutcome.SUCCESS)
        return self._observation(), reward, not more, False, info

    def oracle_action(self) -> dict[str, Any]:
        """The oracle's grasp for the current pick, as an action.

        It reads the simulator's truth, as ``gva trials --model oracle`` does: a baseline and a
        check of the environment, never part of an observation.
        """
        if self._sighting is None:
            raise gymnasium.error.ResetNeeded("call reset() before oracle_action()")
        return self.action_of(self._runner.model.predict_frame(self._sighting.frame,
                                                               self._scene.given), "oracle")

    def action_of(self, prediction: Prediction, name: str = "model") -> dict[str, Any]:
        """A model's prediction as the current pick's action, read as a trial reads it.

        Its target for this pick (a model may leave out the targets already picked: they are
        matched from the end), its grasp pose, stated type and opening.

        Raises:
            perception.errors.InvalidPredictionError: One a pick cannot act on (too few
                targets, no rotation); ``name`` is the model's, for the message.

        """
        if self._sighting is None:
            raise gymnasium.error.ResetNeeded("call reset() before action_of()")
        total, number = len(self._targets), len(self._picks)
        targets = check_prediction(prediction, name, least=total - number, most=total,
                                   label_kind=LabelKind.GRASP_POSE)
        target = targets[number - (total - len(targets))]
        assert target.rotation is not None  # check_prediction: a grasp pose has one
        if target.object_type is not None and target.object_type not in self.object_types:
            raise InvalidPredictionError(f"{name} stated object type {target.object_type!r}, "
                                         f"not one of {', '.join(self.object_types)}")
        stated = 0 if target.object_type is None else self.object_types.index(
            target.object_type) + 1
        return {"position_m": np.asarray(target.position_m, dtype=np.float64),
                "rotation_6d": np.concatenate([target.rotation[:, 0], target.rotation[:, 1]]),
                "object_type": stated,
                "opening_m": np.array([target.opening_m or 0.0])}

    def camera(self) -> PinholeCamera:
        """The calibrated camera the current observation was taken by.

        Its ``K`` and ``T_world_camera`` are the observation's; a model's frame also needs what
        they leave out (the image size, the lens's distortion).
        """
        if self._sighting is None:
            raise gymnasium.error.ResetNeeded("call reset() before camera()")
        return self._sighting.frame.camera

    def render(self) -> np.ndarray | None:
        """The head camera's image now, for ``render_mode="rgb_array"``."""
        return self._runner.render() if self.render_mode == "rgb_array" else None

    def close(self) -> None:
        """Releases the simulator."""
        self._runner.close()

    def _observation(self) -> dict[str, Any]:
        frame = self._runner.sense() if self._sighting is None else self._sighting.frame
        given = self._scene.given
        condition: dict[str, Any] = {"kind": _KINDS.index(given.kind)}
        keys = self._condition_keys
        if "vector" in keys:
            condition["vector"] = given.vector()
        if "sentence" in keys:
            condition["sentence"] = given.value
        if "picture" in keys:
            condition["picture"] = np.array(given.picture)  # a fresh array per call
        joints = self._runner.world.robot.joint_positions(self.joint_names)
        return {"rgb": frame.rgb, "depth_m": frame.depth_m, "K": frame.camera.K,
                "T_world_camera": frame.camera.T_world_camera,
                "joints": np.array([joints[n] for n in self.joint_names]),
                "condition": condition}

    def _target(self, action: dict[str, Any]) -> Target:
        """The grasp an action names, or a clear error naming the field."""
        if not isinstance(action, dict):
            raise InvalidInputError("action", type(action).__name__, "a dict of the action space")
        unknown = sorted(set(action) - set(_ACTION_KEYS))
        missing = sorted({"position_m", "rotation_6d"} - set(action))
        if unknown or missing:
            raise InvalidInputError("action", sorted(action),
                                    "position_m and rotation_6d, optionally object_type and "
                                    "opening_m")
        position = _numbers("position_m", action["position_m"], 3, "3 finite numbers [m]")
        six = _numbers("rotation_6d", action["rotation_6d"], 6,
                       f"6 finite numbers within +-{ROTATION_6D_MOST:g}")
        if float(np.max(np.abs(six))) > ROTATION_6D_MOST:  # its lengths would overflow
            raise InvalidInputError("action['rotation_6d']", six.tolist(),
                                    f"6 finite numbers within +-{ROTATION_6D_MOST:g}")
        length = float(np.linalg.norm(six[:3]))
        x = six[:3] / length if length > 1e-9 else six[:3]
        y = six[3:] - float(x @ six[3:]) * x
        if length <= 1e-9 or float(np.linalg.norm(y)) <= 1e-9 * max(
                1.0, float(np.linalg.norm(six[3:]))):  # parallel, to the precision they have
            raise InvalidInputError("action['rotation_6d']", six.tolist(),
                                    "two non-parallel 3-vectors: the TCP's x and y axes")
        y = y / np.linalg.norm(y)
        rotation = np.column_stack([x, y, np.cross(x, y)])
        kind = _numbers("object_type", action.get("object_type", 0), 1,
                        f"an integer, 0 (not stated) to {len(self.object_types)}")[0]
        if kind != int(kind) or not 0 <= kind <= len(self.object_types):
            raise InvalidInputError("action['object_type']", _shown(action["object_type"]),
                                    f"an integer, 0 (not stated) to {len(self.object_types)}")
        kind = int(kind)
        opening = float(_numbers("opening_m", action.get("opening_m", 0.0), 1,
                                 f"0 (not stated) or a gap in (0, {self.max_opening_m}] m")[0])
        if not (math.isfinite(opening) and 0.0 <= opening <= self.max_opening_m):
            raise InvalidInputError("action['opening_m']", opening,
                                    f"0 (not stated) or a gap in (0, {self.max_opening_m}] m")
        return Target(position, rotation, self.object_types[kind - 1] if kind else None,
                      opening or None)


def _numbers(key: str, value: Any, size: int, allowed: str) -> np.ndarray:
    """An action's ``key`` as ``size`` float64 numbers, or an error naming ``action[key]``.

    The error names the value and ``allowed``; where ``size`` is 1, a number of any shape.
    """
    try:
        numbers = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):  # a string, a ragged list: not numbers at all
        raise InvalidInputError(f"action[{key!r}]", _shown(value), allowed) from None
    if numbers.size != size or (size > 1 and numbers.ndim != 1) or not np.all(
            np.isfinite(numbers)):
        raise InvalidInputError(f"action[{key!r}]", _shown(value), allowed)
    return numbers.reshape(size)


def _shown(value: Any) -> Any:
    """An action's value as a message shows it: an array as a list, a long one cut short."""
    shown = value.tolist() if isinstance(value, np.ndarray) else value
    text = repr(shown)
    return shown if len(text) <= 80 else _Cut(text[:80] + "...")


class _Cut:
    """A value shown by the start of its repr."""

    def __init__(self, text: str) -> None:
        self.text = text

    def __repr__(self) -> str:
        return self.text
