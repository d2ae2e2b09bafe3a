"""A task file's appearance keys, read into an :class:`Appearance` and written back.

The keys are spread over the tables a user finds them in (``[objects] palette``, ``textures``;
``[lighting]``; ``[table] looks``; ``[camera]`` mount keys; ``[appearance] held_out``): what they
mean is :mod:`sim.tasks.appearance`, the rest of the file :mod:`sim.tasks.task_toml`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Protocol

from sim.errors import InvalidInputError
from sim.tasks.appearance import (
    CATALOG_PALETTE,
    Appearance,
    LightVariation,
    builtin_palettes,
    load_palette,
)
from sim.world.textures import TextureKind

LIGHT_RANGES = ("azimuth_deg", "elevation_deg", "colour_temperature_k", "ambient", "diffuse")
"""``[lighting]`` keys that take a number or ``[low, high]`` (:class:`LightVariation`)."""
MOUNT_KEYS = ("mount_offset_mm", "mount_offset_deg")
"""``[camera]`` keys of the mount's offset (:class:`Appearance`), not of the sensor."""


class TaskReader(Protocol):
    """Typed access to a parsed task file (``task_toml``'s reader), errors naming the field."""

    def error(self, field: str, value: Any, allowed: str) -> InvalidInputError:
        """The error of a bad value, naming the file and the field."""

    def get(self, section: str, key: str, kind: type | tuple[type, ...], default: Any,
            allowed: str | None = None) -> Any:
        """``section.key`` of type ``kind``, else ``default``."""

    def number(self, section: str, key: str, default: float) -> float:
        """``section.key`` as a float."""

    def span(self, section: str, key: str) -> tuple[float, float] | None:
        """``section.key``, a number or ``[low, high]``, as ``(low, high)``."""

    def names(self, section: str, key: str, default: tuple[str, ...]) -> tuple[str, ...]:
        """``section.key`` as a list of names."""


def appearance_from_toml(reader: TaskReader, folder: Path | None) -> Appearance:
    """The appearance keys (:mod:`sim.tasks.appearance`); today's world where all are absent."""
    palette_name = reader.get("objects", "palette", str, CATALOG_PALETTE, "a palette's name or "
                              "file")
    try:
        palette = load_palette(palette_name, folder)
    except InvalidInputError as error:
        raise reader.error(error.field, error.value, error.allowed) from None
    if palette is not None and palette_name not in builtin_palettes():
        palette_name = str((folder or Path()).joinpath(palette_name).resolve())
    textures = reader.names("objects", "textures", ("plain",))
    try:
        kinds = tuple(TextureKind(t) for t in textures)
    except ValueError:
        raise reader.error("objects.textures", list(textures), "names among " + ", ".join(
            t.value for t in TextureKind)) from None
    light = LightVariation(**{k: reader.span("lighting", k) for k in LIGHT_RANGES},
                           shadows=reader.get("lighting", "shadows", bool, True, "true or false"))
    return Appearance(
        palette=palette, palette_name=palette_name, textures=kinds,
        tables=reader.names("table", "looks", ("wood",)), light=light,
        mount_offset_mm=reader.number("camera", "mount_offset_mm", 0.0),
        mount_offset_deg=reader.number("camera", "mount_offset_deg", 0.0),
        held_out=reader.get("appearance", "held_out", bool, False, "true or false"))


def appearance_keys(look: Appearance) -> dict[str, Any]:
    """The task file's appearance keys that differ from today's world, as a refusal names them.

    For example ``{"objects.textures": ["print"]}``.
    """
    tables: dict[str, dict[str, Any]] = {"objects": {}, "lighting": {}}
    appearance_to_toml(look, tables)
    return {f"{section}.{key}": value for section, keys in tables.items()
            for key, value in keys.items()}


def appearance_to_toml(look: Appearance, tables: dict[str, dict[str, Any]]) -> None:
    """Adds the task's appearance keys to ``tables``, those that differ from today's world."""
    if look.palette is not None:
        tables["objects"]["palette"] = look.palette_name
    if look.textures != (TextureKind.PLAIN,):
        tables["objects"]["textures"] = [t.value for t in look.textures]
    for key in LIGHT_RANGES:
        if getattr(look.light, key) is not None:
            tables["lighting"][key] = list(getattr(look.light, key))
    if not look.light.shadows:
        tables["lighting"]["shadows"] = False
    for key in MOUNT_KEYS:
        if getattr(look, key):
            tables.setdefault("camera", {})[key] = getattr(look, key)
    if look.tables != ("wood",):
        tables["table"] = {"looks": list(look.tables)}
    if look.held_out:
        tables["appearance"] = {"held_out": True}
