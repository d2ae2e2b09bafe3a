"""The head camera's sensor: which one renders its frames, and which frame it renders.

A :class:`SensorConfig` chooses an ideal pinhole or the D435-like sensor of
:mod:`sim.world.d435` (a task file's ``camera`` table, read by :func:`sensor_from_table`;
records keep :meth:`SensorConfig.to_json`). A :class:`SensorSeed` names a frame: the D435's
noise is drawn per frame from it, and its camera's hand-eye error once per seed, so a trial's
frames depend only on its seed, stream, scene index and pick.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field, fields
from typing import Any

import numpy as np

from sim.errors import InvalidInputError
from sim.world.d435 import D435Config


class SensorKind(enum.Enum):
    """What the head camera renders through (a task file's ``camera.sensor``)."""

    IDEAL = "ideal"  # an exact pinhole: colour and depth from the calibrated pose, no noise
    D435 = "d435"  # this module's lens, noise, invalid depth and hand-eye error


@dataclass(frozen=True)
class SensorConfig:
    """The head camera's sensor: its kind, and the D435's parameters when it is one.

    Attributes:
        kind: Which sensor renders the frames.
        d435: The D435's parameters; with ``SensorKind.IDEAL`` they must stay the defaults
            (an ideal camera has none: a changed one would be recorded yet never used).

    """

    kind: SensorKind = SensorKind.IDEAL
    d435: D435Config = field(default_factory=D435Config)

    def __post_init__(self) -> None:
        if not isinstance(self.kind, SensorKind):
            raise InvalidInputError("sensor", self.kind, _ALLOWED_SENSORS)
        if not isinstance(self.d435, D435Config):
            raise InvalidInputError("d435", self.d435, "a D435Config")
        if self.kind is SensorKind.IDEAL and self.d435 != D435Config():
            changed = [f.name for f in fields(D435Config)
                       if getattr(self.d435, f.name) != getattr(D435Config(), f.name)]
            raise InvalidInputError(changed[0], getattr(self.d435, changed[0]),
                                    "the default unless sensor = 'd435' (the ideal camera has "
                                    "no D435 parameters)")

    def to_json(self) -> dict[str, Any]:
        """The sensor as records keep it and a task file's ``camera`` table reads it back.

        ``{"sensor": "ideal"}``, or ``{"sensor": "d435"}`` with every D435 field (lists for
        tuples): a record names every value it was rendered with.
        """
        if self.kind is SensorKind.IDEAL:
            return {"sensor": self.kind.value}
        values = {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self.d435).items()}
        return {"sensor": self.kind.value} | values

    def describe(self) -> str:
        """One line for messages: the kind, and the D435 fields that differ from the defaults."""
        changed = [f"{f.name}={getattr(self.d435, f.name)!r}" for f in fields(D435Config)
                   if getattr(self.d435, f.name) != getattr(D435Config(), f.name)]
        return self.kind.value + (f" ({', '.join(changed)})" if changed else "")


DEFAULT_SENSOR = SensorKind.D435
"""What the yumi scene is seen through unless a task file's ``[camera] sensor`` or ``--sensor``
says otherwise, in every command (collect, trials, show scene, reproduce real, the Gymnasium
env): the D435, the sensor of the README's tables, so a model is trained and tried in one world.
(:class:`SensorConfig`'s own default stays the ideal camera: records written before sensors
existed, and the paper-sim scene's camera, are ideal.)"""

_ALLOWED_SENSORS = f"one of {', '.join(repr(k.value) for k in SensorKind)}"


def sensor_kind(name: object, what: str = "sensor") -> SensorKind:
    """The sensor kind called ``name`` (``"ideal"``, ``"d435"``; a :class:`SensorKind` is itself).

    The one place a sensor's name becomes its kind: a task file's ``camera.sensor``, a record's,
    ``--sensor``.

    Raises:
        InvalidInputError: ``name`` names no kind; the error's field is ``what``.

    """
    try:
        return SensorKind(name)
    except (ValueError, TypeError):
        raise InvalidInputError(what, name, _ALLOWED_SENSORS) from None


def sensor_from_table(table: Mapping[str, Any], where: str) -> SensorConfig:
    """The sensor a ``camera`` table (or a record :meth:`SensorConfig.to_json` wrote) names.

    ``sensor`` picks the kind (default ``"ideal"``: records always name it, and those from
    before sensors existed are ideal; a task file without it is read by
    :mod:`sim.tasks.task_toml`, where it means the command's sensor); any :class:`D435Config`
    field may follow, by name. Every mistake is an :class:`InvalidInputError` whose field
    starts with ``where`` (e.g. ``"task file my.toml: camera"``).
    """
    if not isinstance(table, Mapping):
        raise InvalidInputError(where, table, "a table such as { sensor = \"d435\" }")
    kind = sensor_kind(table.get("sensor", SensorKind.IDEAL.value), f"{where}.sensor")
    defaults = D435Config()
    names = sorted(f.name for f in fields(D435Config))
    values: dict[str, Any] = {}
    for key, value in table.items():
        if key == "sensor":
            continue
        if key not in names:
            raise InvalidInputError(f"{where}.{key}", value, "sensor, or a D435 parameter: "
                                    f"{', '.join(names)}")
        if kind is SensorKind.IDEAL:
            raise InvalidInputError(f"{where}.{key}", value, "absent unless sensor = 'd435' "
                                    "(the ideal camera has no D435 parameters)")
        values[key] = _parameter(f"{where}.{key}", value, getattr(defaults, key))
    try:
        return SensorConfig(kind, D435Config(**values))
    except InvalidInputError as error:
        raise InvalidInputError(f"{where}.{error.field}", error.value, error.allowed) from None


def _parameter(name: str, value: Any, default: Any) -> Any:
    """One D435 parameter from a table, of its default's type (a bool is no number)."""
    def number(v: Any) -> bool:
        if isinstance(v, bool) or not isinstance(v, int | float):
            return False
        try:
            return math.isfinite(v)
        except OverflowError:  # an int beyond the float range (TOML integers are unbounded)
            return False

    if isinstance(default, tuple):  # the lens: five numbers
        if isinstance(value, list | tuple) and len(value) == 5 and all(map(number, value)):
            return tuple(float(v) for v in value)
        raise InvalidInputError(name, value, "a list of five finite numbers [k1, k2, p1, p2, k3]")
    if isinstance(default, int):
        if isinstance(value, int) and not isinstance(value, bool):
            return value
        raise InvalidInputError(name, value, "an integer >= 1")
    if number(value):
        return float(value)
    raise InvalidInputError(name, value, "a finite number")


SENSOR_MOUNT_TAG = 48_001
"""Heads the entropy of a mount error's seed, apart from the scene streams' ``[seed, ...]``."""
SENSOR_NOISE_TAG = 48_002
"""Heads the entropy of a frame's noise seed."""


@dataclass(frozen=True)
class SensorSeed:
    """Which frame the sensor renders: its noise, and its camera's mount, are drawn from it.

    Attributes:
        seed: The run's seed. The hand-eye error is drawn from it alone: one re-mounted camera
            per seed, the same for a seed's demonstrations and its trials.
        stream: Which of the seed's scene streams (``SeedStream``'s value: train 0, test 1).
        index: The scene's index in the stream.
        frame: The frame of the scene: the pick it is taken before (0 for the first).

    """

    seed: int = 0
    stream: int = 0
    index: int = 0
    frame: int = 0

    def __post_init__(self) -> None:
        for name in ("seed", "stream", "index", "frame"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 0:
                raise InvalidInputError(name, value, "an integer >= 0")

    def noise_rng(self) -> np.random.Generator:
        """The generator of this frame's colour and depth noise."""
        return np.random.default_rng(np.random.SeedSequence(
            [SENSOR_NOISE_TAG, self.seed, self.stream, self.index, self.frame]))

    def mount_rng(self) -> np.random.Generator:
        """The generator of the camera's hand-eye error under this seed."""
        return np.random.default_rng(np.random.SeedSequence([SENSOR_MOUNT_TAG, self.seed]))


__all__ = ["DEFAULT_SENSOR", "SENSOR_MOUNT_TAG", "SENSOR_NOISE_TAG", "SensorConfig", "SensorKind",
           "SensorSeed", "sensor_from_table", "sensor_kind"]
