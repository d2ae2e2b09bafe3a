"""Randomised looks: colours, prints, tables and lamps drawn wider than any variant.

A model trained on a few demonstrations learns the looks it saw (docs/decisions/appearance.md:
320 demonstrations of the train half's colours did not carry to the test half's). Domain
randomisation (Tobin et al., IROS 2017) shows a network so many looks that only the shape is
left to learn from: here every part of every target takes any colour, a printed pattern of the
train half, any table finish, any lamp, and look-alikes stand beside the targets in some
scenes. Two things are never drawn, so the held-out check stays a test of looks never seen:

- the ``household`` palette's held-out (``split = "test"``) colourways: a target whose every
  part lies within :attr:`RandomisedLooks.held_out_margin` (CIE76 colour difference) of such an
  entry of its type is drawn again; so are the held-out patterns (``print``, ``noise``:
  :data:`~sim.tasks.appearance.TEXTURE_SPLIT`'s test half), which no target is given;
- a look-alike's own finish on a target: a target part within the margin of the shape twins'
  unfinished wood is drawn again (a wooden mug *is* the mug twin to a camera).

Tables and lamps are not held out (``[appearance] held_out`` draws them from the full sets in
both halves), so every table finish is drawn. The camera stays where it was calibrated.
"""

from __future__ import annotations

import colorsys
import dataclasses
import math
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np

from perception.objects.catalog import SHAPE_TWINS, get_object_spec
from sim.errors import InvalidInputError, SimError
from sim.tasks.appearance import (
    COLOUR_TEMPERATURE_K,
    ELEVATION_DEG,
    TEXTURE_SPLIT,
    Split,
    load_palette,
)
from sim.tasks.scene_sampling import RANDOMISED_LOOK_STREAM, Scene
from sim.tasks.task_spec import TaskSpec
from sim.world.looks import TABLE_LOOKS, LightLook, ObjectLook, SceneLook, part_colours
from sim.world.textures import VARIANTS, TextureKind

LOOK_ALIKES: tuple[str, ...] = ("colour_twin", "block", "bottle_twin", "mug_twin")
"""The look-alikes a randomised scene may present (the ``varied`` variant's)."""
MAX_COLOUR_DRAWS = 1000
"""Colourways drawn for one target before giving up; the defaults refuse 3 % of the sponge's
and the bottle's and 21 % of the mug's (one part, near four held-out colours or the wood)."""
Range = tuple[float, float]


@dataclass(frozen=True)
class RandomisedLooks:
    """How wide a randomised scene's looks are drawn; each range ``(low, high)`` uniform.

    Attributes:
        saturation, value: Each target part's colour in HSV: the hue uniform over the whole
            circle, these two uniform in their ranges (0 saturation: white, greys, black).
        textures: The patterns a target draws from (the train half only).
        tables: The table finishes a scene draws from.
        azimuth_deg, elevation_deg, colour_temperature_k, ambient, diffuse: The lamp
            (``[lighting]``'s keys; ``varied`` draws 30-85 deg, 2700-6500 K, 0.4-0.8, 0.3-0.7).
        shadow_share: The share of scenes whose objects cast shadows.
        look_alikes: ``(low, high)`` look-alikes (:data:`LOOK_ALIKES`) a scene presents, for a
            task without distractors of its own. 0-2: 1-3 lifted `multiple` beside shape twins
            offline at seeds 10 and 11, but in the seed-0 variant table's 1,320 physics trials
            it picked 20 fewer (other tables -16, shape twins +1; docs/decisions/appearance.md,
            "More look-alikes").
        palette: The palette whose held-out colourways are never drawn.
        held_out_margin: How near (CIE76 delta E) a target's colours may come to a held-out
            colourway of its type, or any part to the look-alikes' wood: 20 is a colour anyone
            names differently (2.3 is a just-noticeable difference).

    """

    saturation: Range = (0.0, 1.0)
    value: Range = (0.15, 1.0)
    textures: tuple[TextureKind, ...] = (TextureKind.PLAIN, TextureKind.STRIPES)
    tables: tuple[str, ...] = tuple(TABLE_LOOKS)
    azimuth_deg: Range = (-180.0, 180.0)
    elevation_deg: Range = (20.0, 90.0)
    colour_temperature_k: Range = (2000.0, 9000.0)
    ambient: Range = (0.3, 0.9)
    diffuse: Range = (0.2, 0.8)
    shadow_share: float = 0.8
    look_alikes: tuple[int, int] = (0, 2)
    palette: str = "household"
    held_out_margin: float = 20.0

    def __post_init__(self) -> None:
        for name, low, high in (("saturation", 0.0, 1.0), ("value", 0.0, 1.0),
                                ("azimuth_deg", -360.0, 360.0),
                                ("elevation_deg", *ELEVATION_DEG),
                                ("colour_temperature_k", *COLOUR_TEMPERATURE_K),
                                ("ambient", 0.0, 1.0), ("diffuse", 0.0, 1.0)):
            value = getattr(self, name)
            if not (isinstance(value, tuple) and len(value) == 2 and all(
                    isinstance(v, float) and math.isfinite(v) for v in value)
                    and low <= value[0] <= value[1] <= high):
                raise InvalidInputError(name, value, f"(low, high) floats with {low:g} <= low "
                                        f"<= high <= {high:g}")
        held_out = [t.value for t in self.textures if TEXTURE_SPLIT.get(t) != Split.TRAIN.value]
        if not self.textures or held_out:
            raise InvalidInputError("textures", [getattr(t, "value", t) for t in self.textures],
                                    "one or more of the train half: " + ", ".join(
                                        t.value for t, half in TEXTURE_SPLIT.items()
                                        if half == Split.TRAIN.value))
        if not (self.tables and set(self.tables) <= set(TABLE_LOOKS)):
            raise InvalidInputError("tables", list(self.tables),
                                    f"names among {', '.join(TABLE_LOOKS)}")
        if not 0.0 <= self.shadow_share <= 1.0:
            raise InvalidInputError("shadow_share", self.shadow_share, "a share in [0, 1]")
        low, high = self.look_alikes
        if not 0 <= low <= high <= len(LOOK_ALIKES):
            raise InvalidInputError("look_alikes", self.look_alikes,
                                    f"(low, high) with 0 <= low <= high <= {len(LOOK_ALIKES)}")
        if not (math.isfinite(self.held_out_margin) and self.held_out_margin >= 0.0):
            raise InvalidInputError("held_out_margin", self.held_out_margin, "a delta E >= 0")
        load_palette(self.palette)  # names the palette if it is unknown

    def to_json(self) -> dict[str, Any]:
        """The settings as a dataset's metadata records them."""
        return {k: [t.value if isinstance(t, TextureKind) else t for t in v]
                if isinstance(v, tuple) else v for k, v in dataclasses.asdict(self).items()}

    def with_look_alikes(self, task: TaskSpec) -> TaskSpec:
        """``task`` as its randomised scenes present it, named ``<task>+randomised``.

        A task without distractors of its own presents ``look_alikes`` of :data:`LOOK_ALIKES`
        (their own seed stream: the scene's objects, poses and targets are the task's); one
        with distractors keeps them as its file says.
        """
        extra: dict[str, Any] = {} if task.distractors else {
            "distractors": LOOK_ALIKES, "distractors_per_scene": self.look_alikes}
        return dataclasses.replace(task, name=f"{task.name}+randomised",
                                   source=f"{task.source} + randomised looks", **extra)

    @cached_property
    def _held_out(self) -> dict[str, tuple[np.ndarray, ...]]:
        """Per target type, each held-out colourway of the palette in CIELAB (parts, 3)."""
        palette = load_palette(self.palette)
        if palette is None:
            return {}
        return {kind: tuple(_lab(entry.colours) for entry in entries
                            if entry.split is Split.TEST)
                for kind, entries in palette.entries}

    @cached_property
    def _look_alike_finishes(self) -> np.ndarray:
        """The shape twins' own colours in CIELAB (n, 3): never a target part's."""
        finishes = {rgba[:3] for twin in SHAPE_TWINS.values()
                    for rgba in part_colours(get_object_spec(twin))}
        return _lab(tuple(_hex(rgb) for rgb in sorted(finishes)))

    def allowed(self, object_type: str, colours: tuple[str, ...]) -> bool:
        """Whether a target of ``object_type`` may wear ``colours`` (see the module docstring)."""
        lab = _lab(colours)
        margin = self.held_out_margin
        near_twin = np.linalg.norm(lab[:, None] - self._look_alike_finishes[None], axis=-1)
        if near_twin.min() < margin:
            return False
        return not any(np.linalg.norm(lab - entry, axis=-1).max() < margin
                       for entry in self._held_out.get(object_type, ()))

    def colourway(self, object_type: str, rng: np.random.Generator) -> tuple[str, ...]:
        """Any colour per part of ``object_type``, drawn again while :meth:`allowed` says no."""
        parts = len(part_colours(get_object_spec(object_type)))
        for _ in range(MAX_COLOUR_DRAWS):
            colours = tuple(_hex(colorsys.hsv_to_rgb(float(rng.uniform(0.0, 1.0)),
                                                     float(rng.uniform(*self.saturation)),
                                                     float(rng.uniform(*self.value))))
                            for _ in range(parts))
            if self.allowed(object_type, colours):
                return colours
        raise SimError(f"randomised looks: no colourway of a {object_type} in {MAX_COLOUR_DRAWS} "
                       f"draws kept {self.held_out_margin:g} delta E from the held-out ones")

    def draw(self, types: tuple[str, ...], distractor: tuple[bool, ...],
             targets: tuple[int, ...], rng: np.random.Generator) -> SceneLook:
        """One scene's look, for objects of ``types`` (``distractor`` flags), in this order.

        Each target a colourway, a pattern and its variant; a ``colour_twin`` the first
        target's colours (its first part's and its last), as :mod:`sim.tasks.appearance` paints
        it; other distractors their catalog colours; then the table and the lamp.
        """
        looks: list[ObjectLook] = []
        for object_type, is_distractor in zip(types, distractor, strict=True):
            if is_distractor:
                looks.append(ObjectLook())
                continue
            colours = self.colourway(object_type, rng)
            texture = self.textures[int(rng.integers(len(self.textures)))]
            variant = 0 if texture is TextureKind.PLAIN else int(rng.integers(VARIANTS))
            looks.append(ObjectLook(colours, texture, variant))
        if targets and "colour_twin" in types:
            first = looks[targets[0]].colours
            assert first is not None  # every target drew a colourway
            looks = [ObjectLook((first[0], first[-1])) if t == "colour_twin" else look
                     for t, look in zip(types, looks, strict=True)]
        table = self.tables[int(rng.integers(len(self.tables)))]
        light = LightLook(float(rng.uniform(*self.azimuth_deg)),
                          float(rng.uniform(*self.elevation_deg)),
                          float(rng.uniform(*self.colour_temperature_k)),
                          float(rng.uniform(*self.ambient)), float(rng.uniform(*self.diffuse)),
                          bool(rng.uniform() < self.shadow_share))
        return SceneLook(tuple(looks), table, light)


def randomised(scene: Scene, looks: RandomisedLooks) -> Scene:
    """``scene`` in a randomised look, drawn from ``SeedSequence([seed, stream, index, 4])``.

    ``scene`` is drawn from a task :meth:`RandomisedLooks.with_look_alikes` made; its objects,
    poses, targets and condition stay as drawn.
    """
    rng = np.random.default_rng(np.random.SeedSequence(
        [scene.seed, int(scene.stream), scene.index, RANDOMISED_LOOK_STREAM]))
    look = looks.draw(tuple(o.object_type for o in scene.objects),
                      tuple(o.distractor for o in scene.objects), scene.targets, rng)
    return dataclasses.replace(scene, look=look)


def _hex(rgb: tuple[float, ...]) -> str:
    """A colour in sRGB [0, 1] as ``#rrggbb``."""
    return "#" + "".join(f"{round(255 * c):02x}" for c in rgb[:3])


def _lab(colours: tuple[str, ...]) -> np.ndarray:
    """``#rrggbb`` colours in CIELAB (D65), (n, 3): where colour differences are measured."""
    srgb = np.array([[int(c[i:i + 2], 16) / 255.0 for i in (1, 3, 5)] for c in colours])
    linear = np.where(srgb <= 0.04045, srgb / 12.92, ((srgb + 0.055) / 1.055) ** 2.4)
    xyz = linear @ np.array([[0.4124, 0.3576, 0.1805], [0.2126, 0.7152, 0.0722],
                             [0.0193, 0.1192, 0.9505]]).T / np.array([0.95047, 1.0, 1.08883])
    f = np.where(xyz > (6 / 29) ** 3, np.cbrt(xyz), xyz / (3 * (6 / 29) ** 2) + 4 / 29)
    return np.stack([116 * f[:, 1] - 16, 500 * (f[:, 0] - f[:, 1]),
                     200 * (f[:, 1] - f[:, 2])], axis=-1)
