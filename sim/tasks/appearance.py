"""Appearance as a task condition: palettes, textures, tables, light and the camera's mount.

A task's :class:`Appearance` says what may vary in how its scenes look; :func:`draw_look` draws
one scene's :class:`~sim.world.looks.SceneLook` from it, from the scene's own appearance seed
stream, so a task that varies its looks presents the same objects, poses, targets and condition
as the task that does not. Every default is today's world: catalog colours, the wooden table,
the camera's white light from its one direction, the camera where it is mounted.

What a scene draws (docs/tasks.md tabulates the keys and bounds):

- each target type's colours from a palette (``[objects] palette``: ``catalog``, the built-in
  ``household`` palette of ``sim/tasks/palettes/``, or a palette file), and a printed pattern
  over them (``[objects] textures``);
- the table's finish (``[table] looks``, :data:`~sim.world.looks.TABLE_LOOKS`);
- the light's direction, colour temperature, ambient and diffuse shares (``[lighting]``);
- the camera mount's offset (``[camera] mount_offset_mm``, ``mount_offset_deg``);
- a ``colour_twin`` distractor's colours: those of the scene's first target.

With ``[appearance] held_out = true``, training scenes draw only the ``train`` half of the
objects' looks (palette entries, textures) and test scenes only the ``test`` half: a model is
tried on colours and patterns its demonstrations never showed, on tables and under lamps drawn
from the same sets as its demonstrations'.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from perception.objects.catalog import OBJECT_TYPES, get_object_spec
from sim.errors import InvalidInputError
from sim.tasks.toml_file import read_toml_file
from sim.world.lighting import Lighting
from sim.world.looks import (
    TABLE_LOOKS,
    LightLook,
    MountOffset,
    ObjectLook,
    SceneLook,
    part_colours,
    rgb_from_hex,
)
from sim.world.textures import VARIANTS, TextureKind

PALETTES = Path(__file__).resolve().parent / "palettes"
CATALOG_PALETTE = "catalog"
"""The palette of no palette: each type keeps its one catalog colour (today's world)."""
MAX_PALETTE_FILE_BYTES = 64 * 1024
"""A palette file is a few kilobytes; a bigger file is refused unread."""
MAX_PALETTE_ENTRIES = 64
"""Most entries per type: more colours than any product range has."""
ELEVATION_DEG = (5.0, 90.0)
"""A light's elevation: from grazing the table (a low window) to overhead [deg]."""
COLOUR_TEMPERATURE_K = (1800.0, 10000.0)
"""A lamp's correlated colour temperature: from candlelight (about 1,850 K) to a clear north
sky (about 10,000 K) [K]. Household and office lamps run 2,700-6,500 K (ANSI C78.377-2017's
nominal CCTs for general lighting, warm white to daylight)."""
MAX_MOUNT_OFFSET_MM = 50.0
"""A camera mount's largest offset per axis [mm]: a bracket re-mounted on another hole."""
MAX_MOUNT_OFFSET_DEG = 10.0
"""A camera mount's largest pan or tilt [deg]: beyond it the workspace leaves the image."""
TEXTURE_SPLIT = {TextureKind.PLAIN: "train", TextureKind.STRIPES: "train",
                 TextureKind.PRINT: "test", TextureKind.NOISE: "test"}
"""Which half of a held-out task each texture belongs to."""



class Split(enum.Enum):
    """Which scenes a palette entry serves when a task holds its looks out."""

    TRAIN = "train"
    TEST = "test"
    BOTH = "both"


@dataclass(frozen=True)
class PaletteEntry:
    """One colourway of a type: a name for people, a ``#rrggbb`` per part, its split."""

    name: str
    colours: tuple[str, ...]
    split: Split = Split.BOTH


@dataclass(frozen=True)
class Palette:
    """Colourways per target type; a type it leaves out keeps its catalog colours.

    Attributes:
        name: ``household`` or the file's name.
        entries: ``(type, entries)`` pairs.
        sha256: The file's digest: records name it, so two palettes of one name differ.

    """

    name: str
    entries: tuple[tuple[str, tuple[PaletteEntry, ...]], ...]
    sha256: str

    def for_type(self, object_type: str) -> tuple[PaletteEntry, ...]:
        """The type's colourways; none where the palette leaves it out."""
        return dict(self.entries).get(object_type, ())


def load_palette(name_or_path: str, folder: Path | None = None) -> Palette | None:
    """The palette a task's ``[objects] palette`` names: None for ``catalog``.

    A built-in name (``household``), or a ``.toml`` file's path, relative to ``folder`` (the
    task file's) where it is not absolute.
    """
    if name_or_path == CATALOG_PALETTE:
        return None
    builtin = PALETTES / f"{name_or_path}.toml"
    if builtin.is_file():
        return _read_palette(builtin)
    path = Path(name_or_path)
    if not path.is_absolute() and folder is not None:
        path = folder / path
    if not (name_or_path.endswith(".toml") and path.is_file()):
        names = ", ".join(sorted([CATALOG_PALETTE, *builtin_palettes()]))
        raise InvalidInputError("objects.palette", name_or_path,
                                f"one of {names}, or an existing palette .toml file")
    return _read_palette(path.resolve())


def builtin_palettes() -> tuple[str, ...]:
    """The palettes that ship with gva (``sim/tasks/palettes/*.toml``)."""
    return tuple(sorted(p.stem for p in PALETTES.glob("*.toml")))


@lru_cache(maxsize=16)
def _read_palette(path: Path) -> Palette:
    """Reads and checks a palette file: every mistake names the file, the field and the value."""
    where = f"palette {path.name}"
    table, digest = read_toml_file(path, where, MAX_PALETTE_FILE_BYTES, "a palette")
    entries = []
    for object_type, rows in table.items():
        if object_type not in OBJECT_TYPES:
            raise InvalidInputError(f"{where}: table", object_type,
                                    f"a target type's [[table]]: {', '.join(OBJECT_TYPES)}")
        if not (isinstance(rows, list) and 0 < len(rows) <= MAX_PALETTE_ENTRIES
                and all(isinstance(r, dict) for r in rows)):
            raise InvalidInputError(f"{where}: {object_type}", type(rows).__name__,
                                    f"1-{MAX_PALETTE_ENTRIES} [[{object_type}]] tables")
        parts = len(part_colours(get_object_spec(object_type)))
        entries.append((object_type, tuple(_palette_entry(row, f"{where}: {object_type}[{k}]",
                                                          parts)
                                           for k, row in enumerate(rows))))
    if not entries:
        raise InvalidInputError(where, "no types", "[[sponge]], [[spray_bottle]] or [[mug]] "
                                "tables of colourways")
    return Palette(path.stem, tuple(entries), digest)


def _palette_entry(row: dict[str, Any], where: str, parts: int) -> PaletteEntry:
    unknown = sorted(set(row) - {"name", "colours", "split"})
    if unknown:
        raise InvalidInputError(f"{where}.{unknown[0]}", row[unknown[0]],
                                "a known key: colours, name, split")
    name, colours, split = row.get("name"), row.get("colours"), row.get("split", "both")
    if not (isinstance(name, str) and 0 < len(name) <= 100 and name.isprintable()):
        raise InvalidInputError(f"{where}.name", name, "1-100 printable characters")
    if not (isinstance(colours, list) and len(colours) == parts):
        raise InvalidInputError(f"{where}.colours", colours,
                                f"{parts} colour{'s' if parts > 1 else ''} '#rrggbb', one per "
                                "part in the catalog's order")
    for colour in colours:
        rgb_from_hex(colour, f"{where}.colours")
    try:
        return PaletteEntry(name, tuple(c.lower() for c in colours), Split(split))
    except ValueError:
        raise InvalidInputError(f"{where}.split", split, "one of 'train', 'test', 'both'"
                                ) from None


Range = tuple[float, float]


def _direction_angles(direction: tuple[float, float, float]) -> tuple[float, float]:
    """Azimuth and elevation [deg] of a light direction."""
    x, y, z = direction
    return math.degrees(math.atan2(y, x)), math.degrees(math.atan2(z, math.hypot(x, y)))


@dataclass(frozen=True)
class LightVariation:
    """How a task's light varies per scene; each range ``(low, high)`` drawn uniformly.

    None keeps the camera's own light for that field (today's: from azimuth 36.9 deg,
    elevation 63.4 deg, white, ambient 0.6, diffuse 0.5, with shadows).
    """

    azimuth_deg: Range | None = None
    elevation_deg: Range | None = None
    colour_temperature_k: Range | None = None
    ambient: Range | None = None
    diffuse: Range | None = None
    shadows: bool = True

    @property
    def is_default(self) -> bool:
        """Whether the light is the camera's own in every scene."""
        return self == LightVariation()

    def check(self, bad: Callable[[str, Any, str], InvalidInputError]) -> None:
        """Raises unless every range lies within its bound (see the module's constants)."""
        bounds = {"azimuth_deg": (-360.0, 360.0, "degrees"), "elevation_deg": (*ELEVATION_DEG,
                                                                                "degrees"),
                  "colour_temperature_k": (*COLOUR_TEMPERATURE_K, "kelvin"),
                  "ambient": (0.0, 1.0, "a share"), "diffuse": (0.0, 1.0, "a share")}
        for name, (low, high, unit) in bounds.items():
            value = getattr(self, name)
            if value is not None and not (len(value) == 2 and all(
                    isinstance(v, float) and math.isfinite(v) for v in value)
                    and low <= value[0] <= value[1] <= high):
                raise bad(f"lighting.{name}", list(value) if isinstance(value, tuple) else value,
                          f"a number or [low, high] with {low:g} <= low <= high <= {high:g} "
                          f"({unit})")
        if not isinstance(self.shadows, bool):
            raise bad("lighting.shadows", self.shadows, "true or false")

    def draw(self, base: Lighting, rng: np.random.Generator) -> LightLook:
        """One scene's light: each range drawn, each None the camera's ``base`` light's."""
        azimuth, elevation = _direction_angles(base.direction)

        def drawn(value: Range | None, default: float) -> float:
            return default if value is None else float(rng.uniform(*value))

        temperature = None if self.colour_temperature_k is None \
            else float(rng.uniform(*self.colour_temperature_k))
        return LightLook(drawn(self.azimuth_deg, azimuth), drawn(self.elevation_deg, elevation),
                         temperature, drawn(self.ambient, base.ambient_coeff),
                         drawn(self.diffuse, base.diffuse_coeff), self.shadows)

    def to_json(self) -> dict[str, Any]:
        """The fields that differ from the camera's own light."""
        return {k: list(v) if isinstance(v, tuple) else v for k, v in self.__dict__.items()
                if v != getattr(LightVariation(), k)}


@dataclass(frozen=True)
class Appearance:
    """What may vary in how a task's scenes look; the defaults are today's world.

    Attributes:
        palette: The target types' colourways (:func:`load_palette`); None: the catalog's.
        palette_name: What the task file named (``catalog``, ``household``, a file).
        textures: The patterns a target's look draws from, uniformly.
        tables: The table finishes a scene draws from, uniformly.
        light: How the light varies.
        mount_offset_mm: Each axis of the camera mount's offset drawn in [-it, it] [mm].
        mount_offset_deg: The mount's pan and tilt each drawn in [-it, it] [deg].
        held_out: Training scenes draw the ``train`` half of palettes and textures, test scenes
            the ``test`` half (tables, light and look-alikes from the whole sets in both).

    """

    palette: Palette | None = None
    palette_name: str = CATALOG_PALETTE
    textures: tuple[TextureKind, ...] = (TextureKind.PLAIN,)
    tables: tuple[str, ...] = ("wood",)
    light: LightVariation = field(default_factory=LightVariation)
    mount_offset_mm: float = 0.0
    mount_offset_deg: float = 0.0
    held_out: bool = False

    @property
    def is_default(self) -> bool:
        """Whether every scene looks as today's world does."""
        return self == Appearance()

    def check(self, bad: Callable[[str, Any, str], InvalidInputError]) -> None:
        """Raises on any value outside what is allowed, naming the task file's field."""
        if not (self.textures and all(isinstance(t, TextureKind) for t in self.textures)
                and len(set(self.textures)) == len(self.textures)):
            raise bad("objects.textures", [getattr(t, "value", t) for t in self.textures],
                      f"distinct names among {', '.join(t.value for t in TextureKind)}")
        if not (self.tables and all(t in TABLE_LOOKS for t in self.tables)
                and len(set(self.tables)) == len(self.tables)):
            raise bad("table.looks", list(self.tables),
                      f"distinct names among {', '.join(TABLE_LOOKS)}")
        self.light.check(bad)
        for name, most, unit in (("mount_offset_mm", MAX_MOUNT_OFFSET_MM, "mm"),
                                 ("mount_offset_deg", MAX_MOUNT_OFFSET_DEG, "deg")):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float) or not (
                    math.isfinite(value) and 0.0 <= value <= most):
                raise bad(f"camera.{name}", value, f"a number in [0, {most:g}] {unit}")
        if not isinstance(self.held_out, bool):
            raise bad("appearance.held_out", self.held_out, "true or false")
        if self.held_out:
            self._check_halves(bad)

    def _check_halves(self, bad: Callable[[str, Any, str], InvalidInputError]) -> None:
        """Held out: palettes and textures need a member in each half, or one half sees none."""
        sets = [("objects.textures", [t.value for t in self.textures],
                 [TEXTURE_SPLIT[t] for t in self.textures])]
        if self.palette is not None:
            sets += [(f"objects.palette {self.palette_name}: {kind}", [e.name for e in entries],
                      [e.split.value for e in entries]) for kind, entries in self.palette.entries]
        for field_name, names, splits in sets:
            if len(names) == 1 and field_name == "objects.textures":
                continue  # not varied: both halves see the one
            for half in ("train", "test"):
                if not any(s in (half, "both") for s in splits):
                    raise bad(field_name, names, f"at least one {half} member when "
                              "appearance.held_out = true (each half draws only its own)")

    def to_json(self) -> dict[str, Any]:
        """The appearance as records keep it: only what differs from today's world."""
        data: dict[str, Any] = {}
        if self.palette is not None:
            data["palette"] = {"name": self.palette_name, "sha256": self.palette.sha256}
        if self.textures != (TextureKind.PLAIN,):
            data["textures"] = [t.value for t in self.textures]
        if self.tables != ("wood",):
            data["tables"] = list(self.tables)
        if not self.light.is_default:
            data["lighting"] = self.light.to_json()
        for name in ("mount_offset_mm", "mount_offset_deg"):
            if getattr(self, name):
                data[name] = getattr(self, name)
        if self.held_out:
            data["held_out"] = True
        return data

    def draws_anything(self, types: tuple[str, ...]) -> bool:
        """Whether a scene of these object types looks other than today's world."""
        return not self.is_default or "colour_twin" in types

    def draw(self, types: tuple[str, ...], distractor: tuple[bool, ...],
             targets: tuple[int, ...], test: bool, base_light: Lighting,
             rng: np.random.Generator) -> SceneLook:
        """One scene's look, for objects of ``types`` (``distractor`` flags), in this order.

        Targets' types take a colourway and a texture, then ``colour_twin`` distractors the
        colours of the scene's first target (its first part's and its last), then the table,
        the light and the mount. Other distractors (the block, the clutter, the shape twins)
        keep their catalog colours. ``test``: the scene is a test scene (a held-out task draws
        the test half).
        """
        half = "test" if test else "train"

        def kept(items: tuple[Any, ...], split: Callable[[Any], str]) -> tuple[Any, ...]:
            if not self.held_out or len(items) == 1:
                return items
            return tuple(i for i in items if split(i) in (half, "both"))

        textures = kept(self.textures, TEXTURE_SPLIT.__getitem__)
        looks: list[ObjectLook] = []
        for object_type, is_distractor in zip(types, distractor, strict=True):
            entries = () if self.palette is None or is_distractor else kept(
                self.palette.for_type(object_type), lambda e: e.split.value)
            colours = None if not entries else entries[int(rng.integers(len(entries)))].colours
            texture = TextureKind.PLAIN if is_distractor else \
                textures[int(rng.integers(len(textures)))]
            variant = 0 if texture is TextureKind.PLAIN else int(rng.integers(VARIANTS))
            looks.append(ObjectLook(colours, texture, variant))
        if targets and "colour_twin" in types:
            first = looks[targets[0]].colours or _catalog_hex(types[targets[0]])
            looks = [ObjectLook((first[0], first[-1])) if t == "colour_twin" else look
                     for t, look in zip(types, looks, strict=True)]
        tables = self.tables  # both halves draw every table: what is held out is the objects'
        table = tables[int(rng.integers(len(tables)))] if len(tables) > 1 else tables[0]
        light = None if self.light.is_default else self.light.draw(base_light, rng)
        mount = None
        if self.mount_offset_mm or self.mount_offset_deg:
            offset = rng.uniform(-self.mount_offset_mm, self.mount_offset_mm, 3) / 1000.0
            pan, tilt = np.radians(rng.uniform(-self.mount_offset_deg, self.mount_offset_deg, 2))
            mount = MountOffset((float(offset[0]), float(offset[1]), float(offset[2])),
                                float(pan), float(tilt))
        return SceneLook(tuple(looks), table, light, mount)


def _catalog_hex(object_type: str) -> tuple[str, ...]:
    """A type's catalog part colours as ``#rrggbb``."""
    return tuple("#" + "".join(f"{round(255 * c):02x}" for c in rgba[:3])
                 for rgba in part_colours(get_object_spec(object_type)))
