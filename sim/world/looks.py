"""What a scene looks like beyond its shapes and poses: colours, textures, table, light, mount.

A :class:`SceneLook` is drawn per scene by :mod:`sim.tasks.appearance` from a task's
appearance conditions and applied here: :func:`dress_object` recolours and textures a body,
:func:`dress_table` the table top, :func:`lighting_for` turns a drawn light into the renderer's
:class:`~sim.world.lighting.Lighting`, :func:`moved_camera` moves the head camera's mount.
Nothing here changes a body's shape or physics: a look is for the camera only, so the same
scene picks the same way whatever it looks like.

Colour temperature: a lamp's light is the colour of a black body at its correlated colour
temperature (CCT), on the Planckian locus; :func:`kelvin_rgb` reads the locus's chromaticity
from Kang et al. (2002), "Design of advanced color temperature control system for HDTV
applications", J. Korean Phys. Soc. 41(6), 865-871 (a cubic fit, 1667-25000 K, within 3e-4
in xy of the locus), and takes it to linear sRGB (IEC 61966-2-1), white-balanced to D65: the
camera keeps a daylight white balance, so 6504 K renders white and a 2700 K lamp orange, as a
fixed-balance robot camera sees them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from perception.objects.catalog import ObjectSpec
from sim.errors import InvalidInputError
from sim.world.head_camera import CameraConfig
from sim.world.lighting import Lighting, TintedLighting
from sim.world.textures import TextureKind, texture_file

HEX_DIGITS = 6
"""A colour is written ``#rrggbb`` (sRGB, as CSS and every colour picker give it)."""


def rgb_from_hex(text: str, field: str = "colour") -> tuple[float, float, float]:
    """``#rrggbb`` as sRGB in [0, 1]; anything else is refused naming ``field``."""
    digits = text[1:] if isinstance(text, str) and text.startswith("#") else ""
    if len(digits) != HEX_DIGITS or any(c not in "0123456789abcdefABCDEF" for c in digits):
        raise InvalidInputError(field, text, "a colour written '#rrggbb' (hex sRGB)")
    return tuple(int(digits[i:i + 2], 16) / 255.0 for i in (0, 2, 4))  # type: ignore[return-value]


@dataclass(frozen=True)
class ObjectLook:
    """How one object of a scene looks.

    Attributes:
        colours: ``#rrggbb`` per part of its type (:func:`part_colours`: its catalog colours,
            distinct, in the order its primitives first use them); None keeps the catalog's.
        texture: A printed pattern over every part (:class:`TextureKind`), modulating its
            colour; ``plain``: none.
        variant: Which of the pattern's seeded variants (:data:`~sim.world.textures.VARIANTS`).

    """

    colours: tuple[str, ...] | None = None
    texture: TextureKind = TextureKind.PLAIN
    variant: int = 0

    @property
    def is_catalog(self) -> bool:
        """Whether the object looks as the catalog made it."""
        return self.colours is None and self.texture is TextureKind.PLAIN

    def to_json(self) -> dict[str, Any]:
        """The look as a record keeps it."""
        return ({} if self.colours is None else {"colours": list(self.colours)}) | (
            {} if self.texture is TextureKind.PLAIN
            else {"texture": self.texture.value, "variant": self.variant})


@dataclass(frozen=True)
class TableLook:
    """A table top's finish: a colour over a pattern; the URDF's wood where ``colour`` is None."""

    colour: str | None = None
    texture: TextureKind = TextureKind.PLAIN


TABLE_LOOKS: dict[str, TableLook] = {
    "wood": TableLook(),  # pybullet_data's table: light maple, the scene's table since Table III
    "white": TableLook("#f0f0ec"),  # white laminate (an office desk, a lab bench)
    "grey": TableLook("#8c8c8a", TextureKind.NOISE),  # grey linoleum
    "dark-wood": TableLook("#6b4a2e", TextureKind.STRIPES),  # walnut, its grain
    "black": TableLook("#2b2b2b"),  # a black worktop
    "cloth": TableLook("#5a7fa8", TextureKind.PRINT),  # a blue printed tablecloth
    "beige": TableLook("#d9c7a3", TextureKind.NOISE),  # a beige kitchen counter
    "green-mat": TableLook("#3d6b4f", TextureKind.STRIPES),  # a green cutting mat, its grid
}
"""The table finishes a task may draw from (``[table] looks``). ``wood`` is today's table."""


@dataclass(frozen=True)
class LightLook:
    """The light of one scene, as drawn (each field fixed for the scene).

    Attributes:
        azimuth_deg: Direction toward the light about the vertical, from +x toward +y [deg].
        elevation_deg: The light's height above the table's plane [deg].
        colour_temperature_k: The lamp's correlated colour temperature [K]; None: white.
        ambient_coeff, diffuse_coeff: The renderer's ambient and diffuse shares.
        shadows: Whether objects cast shadows.

    """

    azimuth_deg: float
    elevation_deg: float
    colour_temperature_k: float | None
    ambient_coeff: float
    diffuse_coeff: float
    shadows: bool = True

    def to_json(self) -> dict[str, Any]:
        """The light as a record keeps it (rounded as poses are)."""
        return {"azimuth_deg": round(self.azimuth_deg, 6),
                "elevation_deg": round(self.elevation_deg, 6),
                "colour_temperature_k": None if self.colour_temperature_k is None
                else round(self.colour_temperature_k, 3),
                "ambient_coeff": round(self.ambient_coeff, 6),
                "diffuse_coeff": round(self.diffuse_coeff, 6), "shadows": self.shadows}


@dataclass(frozen=True)
class MountOffset:
    """How far the head camera's mount stands off its nominal pose in one scene.

    Unlike the D435's hand-eye error, the camera's calibration follows it: the frames carry the
    moved camera's pose (a robot recalibrated after its camera was re-mounted), and the model
    sees the workspace from another viewpoint.

    Attributes:
        offset_m: The optical centre's shift in the world [m].
        pan_rad: The optical axis turned about the world vertical [rad].
        tilt_rad: The optical axis turned down (+) or up (-) [rad].

    """

    offset_m: tuple[float, float, float]
    pan_rad: float
    tilt_rad: float

    def to_json(self) -> dict[str, Any]:
        """The offset as a record keeps it (mm and deg, rounded)."""
        return {"offset_mm": [round(1000.0 * v, 3) for v in self.offset_m],
                "pan_deg": round(math.degrees(self.pan_rad), 4),
                "tilt_deg": round(math.degrees(self.tilt_rad), 4)}


@dataclass(frozen=True)
class SceneLook:
    """What one scene looks like: each object's look (in the scene's object order) and the rest.

    The defaults are the world as it always looked: catalog colours, the wooden table, the
    camera's own light, the camera where it is mounted.
    """

    objects: tuple[ObjectLook, ...]
    table: str = "wood"
    light: LightLook | None = None
    mount: MountOffset | None = None

    def to_json(self) -> dict[str, Any]:
        """The look as a scene's record keeps it: only what differs from today's world."""
        return ({"objects": [o.to_json() for o in self.objects]}
                if any(not o.is_catalog for o in self.objects) else {}) | (
            {} if self.table == "wood" else {"table": self.table}) | (
            {} if self.light is None else {"light": self.light.to_json()}) | (
            {} if self.mount is None else {"mount": self.mount.to_json()})


def part_colours(spec: ObjectSpec) -> tuple[tuple[float, float, float, float], ...]:
    """The distinct colours of ``spec``'s primitives, in the order they first appear."""
    seen: list[tuple[float, float, float, float]] = []
    for primitive in spec.primitives:
        if primitive.rgba not in seen:
            seen.append(primitive.rgba)
    return tuple(seen)


def dress_object(client: Any, body: int, spec: ObjectSpec, look: ObjectLook) -> None:
    """Gives ``body`` (made from ``spec``, one visual shape per primitive) ``look``.

    Each primitive takes its part's colour; a texture modulates every primitive's colour.
    """
    if look.is_catalog:
        return
    parts = part_colours(spec)
    if look.colours is not None and len(look.colours) != len(parts):
        raise InvalidInputError(f"{spec.name} look colours", list(look.colours),
                                f"{len(parts)} colours, one per part of a {spec.name}")
    texture = -1 if look.texture is TextureKind.PLAIN else int(
        client.loadTexture(str(texture_file(look.texture, look.variant))))
    for index, primitive in enumerate(spec.primitives):
        rgb = primitive.rgba[:3] if look.colours is None else rgb_from_hex(
            look.colours[parts.index(primitive.rgba)])
        options: dict[str, Any] = {"rgbaColor": [*rgb, primitive.rgba[3]]}
        if texture >= 0:
            options["textureUniqueId"] = texture
        client.changeVisualShape(body, -1, shapeIndex=index, **options)


def dress_table(client: Any, table_id: int, name: str) -> None:
    """Gives the table top the finish called ``name`` (:data:`TABLE_LOOKS`)."""
    look = TABLE_LOOKS.get(name)
    if look is None:
        raise InvalidInputError("table look", name, f"one of {', '.join(TABLE_LOOKS)}")
    if look.colour is None:
        return
    texture = texture_file(look.texture, 0, tiled=True)
    client.changeVisualShape(table_id, -1, rgbaColor=[*rgb_from_hex(look.colour), 1.0],
                             textureUniqueId=int(client.loadTexture(str(texture))))


def kelvin_rgb(temperature_k: float) -> tuple[float, float, float]:
    """A black body's colour at ``temperature_k`` as a light colour, its largest channel 1.

    Planckian locus chromaticity after Kang et al. (2002), valid 1667-25000 K; to linear sRGB
    (IEC 61966-2-1's XYZ matrix), each channel divided by D65's (6504 K renders white).
    """
    if not 1667.0 <= temperature_k <= 25000.0:
        raise InvalidInputError("colour_temperature_k", temperature_k,
                                "a temperature in [1667, 25000] K (the locus fit's range)")
    rgb = _linear_srgb(temperature_k) / _linear_srgb(6504.0)
    return tuple(float(v) for v in rgb / rgb.max())  # type: ignore[return-value]


def planck_xy(temperature_k: float) -> tuple[float, float]:
    """CIE 1931 chromaticity (x, y) of the Planckian locus at ``temperature_k`` (Kang 2002)."""
    t = temperature_k
    if t <= 4000.0:
        x = -0.2661239e9 / t**3 - 0.2343589e6 / t**2 + 0.8776956e3 / t + 0.179910
    else:
        x = -3.0258469e9 / t**3 + 2.1070379e6 / t**2 + 0.2226347e3 / t + 0.240390
    if t <= 2222.0:
        y = -1.1063814 * x**3 - 1.34811020 * x**2 + 2.18555832 * x - 0.20219683
    elif t <= 4000.0:
        y = -0.9549476 * x**3 - 1.37418593 * x**2 + 2.09137015 * x - 0.16748867
    else:
        y = 3.0817580 * x**3 - 5.87338670 * x**2 + 3.75112997 * x - 0.37001483
    return x, y


_XYZ_TO_LINEAR_SRGB = np.array([[3.2406, -1.5372, -0.4986],
                                [-0.9689, 1.8758, 0.0415],
                                [0.0557, -0.2040, 1.0570]])
"""IEC 61966-2-1 (sRGB): CIE XYZ (D65) to linear RGB."""


def _linear_srgb(temperature_k: float) -> np.ndarray:
    x, y = planck_xy(temperature_k)
    xyz = np.array([x / y, 1.0, (1.0 - x - y) / y])
    return np.clip(_XYZ_TO_LINEAR_SRGB @ xyz, 1e-6, None)


def lighting_for(base: Lighting, light: LightLook | None) -> Lighting:
    """``base`` (the camera's light, at the task's brightness) as ``light`` draws it."""
    if light is None:
        return base
    azimuth, elevation = math.radians(light.azimuth_deg), math.radians(light.elevation_deg)
    direction = (math.cos(elevation) * math.cos(azimuth), math.cos(elevation) * math.sin(azimuth),
                 math.sin(elevation))
    colour = (1.0, 1.0, 1.0) if light.colour_temperature_k is None \
        else kelvin_rgb(light.colour_temperature_k)
    return TintedLighting(direction=direction, brightness=base.brightness,
                          ambient_coeff=light.ambient_coeff, diffuse_coeff=light.diffuse_coeff,
                          specular_coeff=base.specular_coeff, shadows=light.shadows,
                          tint_rgb=colour)


def moved_camera(config: CameraConfig, mount: MountOffset | None) -> CameraConfig:
    """``config`` with its optical centre shifted and its axis turned by ``mount``."""
    if mount is None:
        return config
    position = np.asarray(config.position_m) + np.asarray(mount.offset_m)
    axis = np.asarray(config.target_m) - np.asarray(config.position_m)
    distance = float(np.linalg.norm(axis))
    heading = math.atan2(axis[1], axis[0]) + mount.pan_rad
    down = math.asin(-axis[2] / distance) + mount.tilt_rad
    turned = distance * np.array([math.cos(down) * math.cos(heading),
                                  math.cos(down) * math.sin(heading), -math.sin(down)])
    target = position + turned
    return replace(config, position_m=(float(position[0]), float(position[1]), float(position[2])),
                   target_m=(float(target[0]), float(target[1]), float(target[2])))
