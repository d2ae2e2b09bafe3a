"""Tasks as data: TOML files read into a frozen :class:`TaskSpec`.

A task says which objects are presented, which of them are the targets and in what order,
what the top-down condition names, and how the scene is drawn (placement, yaw, spacing,
lighting, distractors). The paper's four tasks (Table I) ship as ``sim/tasks/task_files/*.toml``;
a user writes a new one as a TOML file and passes its path wherever a task name is taken::

    name = "two-sponges-left"
    description = "Two sponges, one on each side; pick the one the condition names."

    [objects]
    choose = "same_type"      # random | one_of_each | same_type
    count = 2

    [targets]
    select = "condition"      # all | condition

    [condition]
    kind = "side"             # none | object_type | side
    given_as = "one_hot"      # one_hot | text (with [condition.phrases]) | image

    [placement]
    sides = true              # one object each side of the workspace's centre line
    yaw_deg = [-180.0, 180.0]
    min_spacing_m = 0.12

    [lighting]
    brightness = 1.0          # 1 = the scene's normal light; 0.3 is a dim room

    [distractors]
    types = []                # extra objects that are never targets (yumi: also "block" and
                              # the clutter: "drink_can", "notebook", "marker", "glue_stick")
    per_scene = [0, 2]        # optional: each scene presents 0-2 of the types, drawn anew

    [camera]                  # optional: without it, the command's sensor (--sensor, else d435)
    sensor = "ideal"          # ideal | d435 (then any D435Config field by name)

    Appearance keys (optional, :mod:`sim.tasks.appearance`; every default today's world):
    ``[objects] palette`` and ``textures``, ``[lighting] azimuth_deg``, ``elevation_deg``,
    ``colour_temperature_k``, ``ambient``, ``diffuse``, ``shadows``, ``[table] looks``,
    ``[camera] mount_offset_mm`` and ``mount_offset_deg``, ``[appearance] held_out``, and the
    look-alike distractors ``bottle_twin``, ``mug_twin`` and ``colour_twin``.

    [disturbance]             # optional: the target moves during the pick (issue 36)
    move_m = [0.03, 0.08]     # see sim/tasks/disturbance.py

A task is valid in both scenes: the object types come from the scene (``paper-sim``: duck,
soccer ball, mug; ``yumi``: sponge, spray bottle, mug, plus a wooden block and table clutter as
distractors only), and so does the workspace unless the task narrows it with
``[placement] x_m = [lo, hi]`` and ``y_m = [lo, hi]``.

A task file is user input: every number must be finite and within the range below, and every
mistake is an :class:`~sim.errors.InvalidInputError` naming the file, the field, the value and
what is allowed. The ranges (and why each bound) are tabulated in ``docs/tasks.md``.
"""

from __future__ import annotations

import dataclasses
import enum
import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

from perception.interface import ConditionKind
from perception.interface import InvalidInputError as PerceptionInputError
from robots.description import CameraMount
from sim.errors import InvalidInputError
from sim.tasks.appearance import Appearance
from sim.tasks.disturbance import Disturbance
from sim.tasks.phrasings import Phrasings
from sim.world.head_camera import CameraConfig
from sim.world.sensor import DEFAULT_SENSOR, SensorConfig, SensorKind

SIDES = ("left", "right")
"""Side condition values: ``left`` is +y (the robot's left, the image's left)."""

MAX_OBJECTS = 12
"""Most objects a scene presents, distractors included. The objects are ~10 cm across and the
larger workspace (``paper-sim``, 0.28 m x 0.36 m) holds 12 of them side by side (3 x 4 at 0.1 m);
more would overlap, and every body slows each physics step, depth image and plan."""
MAX_SPACING_M = 0.5
"""Largest ``placement.min_spacing_m`` [m]: wider than either scene's workspace is across."""
MAX_PLACEMENT_ABS_M = 1.0
"""``placement.x_m`` and ``y_m`` lie within +-1 m of the robot (its arms reach ~0.6 m); the scene
then checks them against its own workspace."""
MAX_YAW_DEG = 360.0
"""``placement.yaw_deg`` lies in [-360, 360] degrees."""
MAX_BRIGHTNESS = 2.0
"""``lighting.brightness`` lies in (0, 2]: from dark up to twice the scene's normal light."""
MAX_NAME_CHARS = 100
"""A task's name is 1-100 printable characters: it is shown in progress bars and one-line errors."""
MAX_DESCRIPTION_CHARS = 1000
"""A description is a sentence or two for people."""
_LENS_CHECK_CAMERA = CameraConfig.for_mount(CameraMount((0.0, 0.0, 1.0), (1.0, 0.0, 0.0)))
"""The head camera's image (size, fields of view) on an arbitrary mount: a task's lens is checked
over the image alone, which every robot's camera shares (``camera_config``), not its placement."""


class ObjectChoice(enum.Enum):
    """How the presented objects' types are drawn."""

    RANDOM = "random"  # ``count`` objects, each of a random type
    ONE_OF_EACH = "one_of_each"  # one object of every type of the scene
    SAME_TYPE = "same_type"  # ``count`` objects of one random type


class ConditionForm(enum.Enum):
    """How the condition is given to the model: a one-hot name, a sentence, a picture."""

    ONE_HOT = "one_hot"  # the paper's: a one-hot type or side
    TEXT = "text"  # a sentence drawn from the task's phrasings of the target
    IMAGE = "image"  # a picture of an object of the wanted type, from scenes of its own


class TargetSelection(enum.Enum):
    """Which presented objects are targets."""

    ALL = "all"  # every object, ordered by the scene's type order, then from right to left
    CONDITION = "condition"  # the one object the condition names


@dataclass(frozen=True)
class TaskSpec:
    """One task, as read from its TOML file (see the module docstring for the layout).

    Args:
        name: The task's name.
        description: One sentence for people.
        objects: How object types are drawn.
        count: How many objects are presented (``one_of_each``: the scene's type count).
        balance_types: Training scenes take the types in turn, each block of as many scenes
            as there are types a seeded shuffle of them, so 20 demonstrations of three types
            hold 6 or 7 of each, as a person recording them would; test scenes stay random.
            For a scene of one drawn type (``random`` with one object, or ``same_type``), and
            for the type a condition names among one object of each (:attr:`types_take_turns`).
        targets: Which objects are targets.
        condition: What the top-down condition names.
        given_as: How the model is given it (``[condition] given_as``).
        phrasings: The sentences per target a text condition draws from
            (``[condition.phrases.train]`` and ``[condition.phrases.test]``); None otherwise.
        sides: Place one object on each side of the workspace's centre line (y = centre).
        yaw_range_rad: Range of object yaw about the vertical [rad].
        min_spacing_m: Smallest distance between object centres [m].
        workspace_x_m, workspace_y_m: Narrower placement ranges than the scene's [m]; None
            keeps the scene's.
        brightness: Light level, 1 = the scene's normal light.
        distractors: Types of extra objects that are presented but never targets.
        distractors_per_scene: ``(low, high)``: each scene presents a number drawn uniformly in
            [low, high] of the distinct ``distractors``, chosen without replacement; None (the
            default): every scene presents them all.
        camera: The head camera's sensor as the task file names it (``[camera] sensor``): the
            ideal pinhole, or a D435's. None (a file without one): the command's sensor, its
            ``--sensor`` or else :data:`~sim.world.sensor.DEFAULT_SENSOR`, the D435
            (:mod:`sim.tasks.task_sensor`); :attr:`sensor` is what renders it.
        disturbance: How the target moves during a pick (``[disturbance]``,
            :mod:`sim.tasks.disturbance`); None (the default): it lies still. It needs the
            ``yumi`` scene's physics: the trial runner applies it.
        appearance: What may vary in how the scenes look (palettes, textures, table, light,
            camera mount: :mod:`sim.tasks.appearance`); the default is today's world.
        source: The file the task came from.

    """

    name: str
    description: str = ""
    objects: ObjectChoice = ObjectChoice.RANDOM
    count: int = 1
    balance_types: bool = False
    targets: TargetSelection = TargetSelection.ALL
    condition: ConditionKind = ConditionKind.NONE
    given_as: ConditionForm = ConditionForm.ONE_HOT
    phrasings: Phrasings | None = None
    sides: bool = False
    yaw_range_rad: tuple[float, float] = (-math.pi, math.pi)
    min_spacing_m: float = 0.12
    workspace_x_m: tuple[float, float] | None = None
    workspace_y_m: tuple[float, float] | None = None
    brightness: float = 1.0
    distractors: tuple[str, ...] = ()
    distractors_per_scene: tuple[int, int] | None = None
    camera: SensorConfig | None = None
    disturbance: Disturbance | None = None
    appearance: Appearance = dataclasses.field(default_factory=Appearance)
    source: str = "<code>"

    def __post_init__(self) -> None:
        if not (isinstance(self.name, str) and 0 < len(self.name) <= MAX_NAME_CHARS
                and self.name.isprintable()):
            raise InvalidInputError(f"task file {self.source}: name", brief(self.name),
                                    f"1-{MAX_NAME_CHARS} printable characters")
        where = f"task {self.name!r} ({self.source})"

        def bad(field: str, value: Any, allowed: str) -> InvalidInputError:
            return InvalidInputError(f"{where}: {field}", brief(value), allowed)

        if len(self.description) > MAX_DESCRIPTION_CHARS:
            raise bad("description", self.description,
                      f"at most {MAX_DESCRIPTION_CHARS} characters")
        if not 1 <= self.count <= MAX_OBJECTS:
            raise bad("objects.count", self.count, f"an integer in [1, {MAX_OBJECTS}] (the most "
                      "objects a scene presents, distractors included)")
        per_scene = self.distractors_per_scene
        if per_scene is not None:
            _check_per_scene(per_scene, self.distractors, self.count, bad)
        elif self.count + len(self.distractors) > MAX_OBJECTS:
            raise bad("distractors.types", list(self.distractors),
                      f"at most {MAX_OBJECTS - self.count} types (objects.count + distractors "
                      f"<= {MAX_OBJECTS})")
        if self.balance_types and not self.types_take_turns:
            raise bad("objects.balance_types", True, "false unless objects.choose = 'same_type', "
                      "or 'random' with objects.count = 1 (one drawn type a scene), or "
                      "'one_of_each' with a condition.kind = 'object_type' naming the target")
        if self.targets is TargetSelection.CONDITION and self.condition is ConditionKind.NONE:
            raise bad("condition.kind", "none", "object_type or side when targets.select = "
                      "'condition' (the condition must name the target)")
        if self.targets is TargetSelection.ALL and self.condition is not ConditionKind.NONE:
            raise bad("targets.select", "all", "'condition' when condition.kind is "
                      f"{self.condition.value!r}")
        one_of_each = self.objects is ObjectChoice.ONE_OF_EACH
        if self.condition is ConditionKind.OBJECT_TYPE and not one_of_each:
            raise bad("objects.choose", self.objects.value, "'one_of_each' with condition.kind = "
                      "'object_type' (the type must name exactly one object)")
        if self.condition is ConditionKind.SIDE and not (self.sides and self.count == 2):
            raise bad("placement.sides", self.sides, "true, with objects.count = 2, when "
                      "condition.kind = 'side' (one object on each side)")
        if self.condition in (ConditionKind.TEXT, ConditionKind.IMAGE):
            raise bad("condition.kind", self.condition.value, "none, object_type or side (what "
                      "is named; condition.given_as says in what form)")
        if self.given_as is not ConditionForm.ONE_HOT and self.condition is ConditionKind.NONE:
            raise bad("condition.given_as", self.given_as.value, "'one_hot' without a condition")
        if self.given_as is ConditionForm.IMAGE and self.condition is not \
                ConditionKind.OBJECT_TYPE:
            raise bad("condition.given_as", "image", "'one_hot' or 'text' when condition.kind "
                      "is 'side' (a picture shows an object, not a side)")
        if (self.given_as is ConditionForm.TEXT) != (self.phrasings is not None):
            raise bad("condition.phrases", "absent" if self.phrasings is None else "given",
                      "a [condition.phrases] table exactly when condition.given_as = 'text'")
        if self.sides and self.count != 2:
            raise bad("objects.count", self.count, "2 when placement.sides = true")
        low, high = (math.degrees(a) for a in self.yaw_range_rad)
        if not (_finite(low, high) and -MAX_YAW_DEG <= low < high <= MAX_YAW_DEG):
            raise bad("placement.yaw_deg", [low, high],
                      "[low, high] with -360 <= low < high <= 360")
        if not (_finite(self.min_spacing_m) and 0.0 <= self.min_spacing_m <= MAX_SPACING_M):
            raise bad("placement.min_spacing_m", self.min_spacing_m,
                      f"a distance in [0, {MAX_SPACING_M}] m")
        for field, value in (("x_m", self.workspace_x_m), ("y_m", self.workspace_y_m)):
            if value is not None and not (_finite(*value) and -MAX_PLACEMENT_ABS_M <= value[0]
                                          < value[1] <= MAX_PLACEMENT_ABS_M):
                raise bad(f"placement.{field}", list(value), "[low, high] in metres with "
                          f"-{MAX_PLACEMENT_ABS_M:g} <= low < high <= {MAX_PLACEMENT_ABS_M:g}")
        if not (_finite(self.brightness) and 0.0 < self.brightness <= MAX_BRIGHTNESS):
            raise bad("lighting.brightness", self.brightness,
                      f"a number in (0, {MAX_BRIGHTNESS:g}]")
        if not (self.camera is None or isinstance(self.camera, SensorConfig)):
            raise bad("camera", self.camera, "a SensorConfig or None")
        if not (self.disturbance is None or isinstance(self.disturbance, Disturbance)):
            raise bad("disturbance", self.disturbance, "a Disturbance or None")
        if not isinstance(self.appearance, Appearance):
            raise bad("appearance", self.appearance, "an Appearance")
        self.appearance.check(bad)
        lens = self.sensor.d435.colour_distortion_k1_k2_p1_p2_k3
        try:  # one-to-one over the head camera's image (and beyond): PinholeCamera checks it
            replace(_LENS_CHECK_CAMERA.pinhole, distortion_k1_k2_p1_p2_k3=lens)
        except PerceptionInputError as error:
            raise bad("camera.colour_distortion_k1_k2_p1_p2_k3", list(lens),
                      error.allowed) from None

    @property
    def sensor(self) -> SensorConfig:
        """The sensor the yumi scene is rendered through: ``camera``, else the D435 default."""
        return SensorConfig(DEFAULT_SENSOR) if self.camera is None else self.camera

    @property
    def draws_one_type(self) -> bool:
        """Whether each scene draws one object type (``balance_types`` can take them in turn)."""
        return self.objects is ObjectChoice.SAME_TYPE or (
            self.objects is ObjectChoice.RANDOM and self.count == 1)

    @property
    def types_take_turns(self) -> bool:
        """Whether ``balance_types`` can take the demonstrated types in turn.

        The one type a scene draws, or the type a condition names among one object of each.
        """
        return self.draws_one_type or (
            self.objects is ObjectChoice.ONE_OF_EACH
            and self.condition is ConditionKind.OBJECT_TYPE
            and self.targets is TargetSelection.CONDITION)

    @property
    def distractor_count_range(self) -> tuple[int, int]:
        """The fewest and the most distractors a scene of this task presents."""
        if self.distractors_per_scene is None:
            return len(self.distractors), len(self.distractors)
        return self.distractors_per_scene

    def recorded_fields(self) -> dict[str, Any]:
        """The fields records keep of the task (run identities, datasets' task records).

        Without its source; the sensor as ``"camera"`` (:meth:`SensorConfig.to_json`) unless
        it is the ideal camera, and ``"distractors_per_scene"``, ``"disturbance"``
        (:meth:`Disturbance.to_json`) and ``"appearance"`` (:meth:`Appearance.to_json`) only
        where set, so records from before they existed (all ideal, every distractor presented,
        targets lying still, today's looks) are the same task. The sensor recorded is
        :attr:`sensor`, the one that renders: a task whose file names none records the D435
        (the default) in full, as a task file naming it does, never the ideal camera's omission.
        """
        appearance = self.appearance
        data = dataclasses.asdict(dataclasses.replace(self, appearance=Appearance()))
        data.pop("source")
        data.pop("camera")
        data.pop("disturbance")
        data.pop("appearance")
        if not appearance.is_default:
            data["appearance"] = appearance.to_json()
        if self.disturbance is not None:
            data["disturbance"] = self.disturbance.to_json()
        if self.distractors_per_scene is None:
            data.pop("distractors_per_scene")
        if self.sensor.kind is not SensorKind.IDEAL:
            data["camera"] = self.sensor.to_json()
        return data

    @property
    def model_condition(self) -> ConditionKind:
        """The kind of condition the model is given: what is named, or a sentence, a picture."""
        return {ConditionForm.ONE_HOT: self.condition, ConditionForm.TEXT: ConditionKind.TEXT,
                ConditionForm.IMAGE: ConditionKind.IMAGE}[self.given_as]


def spaced_for(task: TaskSpec, spacing_m: float | None) -> TaskSpec:
    """``task`` with its objects at least ``spacing_m`` apart, as a robot's hand needs them.

    Unchanged where the task keeps them as far apart already or ``spacing_m`` is None (the
    YuMi's hand fits every task's own spacing); its identity then records the wider spacing.
    """
    if spacing_m is None or task.min_spacing_m >= spacing_m:
        return task
    return replace(task, min_spacing_m=spacing_m)


def _check_per_scene(per_scene: Any, types: tuple[str, ...], count: int,
                     bad: Callable[[str, Any, str], InvalidInputError]) -> None:
    """Refuses a ``distractors.per_scene`` that is not ``[low, high]`` of the listed types."""
    field = "distractors.per_scene"
    value = list(per_scene) if isinstance(per_scene, tuple | list) else per_scene
    if not (isinstance(value, list) and len(value) == 2
            and all(isinstance(v, int) and not isinstance(v, bool) for v in value)):
        raise bad(field, value, "a list of two integers [low, high]")
    low, high = value
    if not 0 <= low <= high <= len(types):
        raise bad(field, value, f"[low, high] with 0 <= low <= high <= {len(types)} (the number "
                  "of distractors.types)")
    if count + high > MAX_OBJECTS:
        raise bad(field, value, f"[low, high] with high <= {MAX_OBJECTS - count} (objects.count "
                  f"+ distractors <= {MAX_OBJECTS})")
    if len(set(types)) != len(types):
        raise bad("distractors.types", list(types), "distinct types when distractors.per_scene "
                  "is given (each is drawn at most once a scene)")


def _finite(*values: float) -> bool:
    return all(finite_number(v) for v in values)


def finite_number(value: Any) -> bool:
    """Whether ``value`` is an int or float (no bool) that a float holds, and not NaN or inf."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return False
    try:
        return math.isfinite(value)
    except OverflowError:  # an int beyond the float range
        return False


_SHOWN_CHARS = 120
"""Longer values are shortened in error messages (a message stays one readable line)."""


class _Shown:
    """A value too long for a one-line message, shown by the start of its repr and its length."""

    def __init__(self, text: str) -> None:
        self.text = text

    def __repr__(self) -> str:
        return f"{self.text[:_SHOWN_CHARS - 20]}... ({len(self.text)} characters)"


def brief(value: Any) -> Any:
    """``value``, or a shortened stand-in when its repr would not fit a one-line message."""
    try:
        text = repr(value)
    except RecursionError:  # lists nested hundreds deep: tomllib read them, repr cannot
        return _Shown("[" * _SHOWN_CHARS)
    return _Shown(text) if len(text) > _SHOWN_CHARS else value
