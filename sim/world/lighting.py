"""The light a camera image is rendered with: PyBullet's one directional lamp, plain or tinted.

Apart from the camera so a task's looks (colour temperature, direction, strength) can be drawn
and recorded without the renderer (:mod:`sim.tasks.appearance`, :mod:`sim.world.looks`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from sim.errors import InvalidInputError


@dataclass(frozen=True)
class Lighting:
    """The one directional light of PyBullet's software renderer.

    Attributes:
        direction: Points from the scene toward the light (world frame, any length > 0).
        brightness: Scales the light's colour; 1 is a bright lab, 0.3 a dim room.
        ambient_coeff: Share of each surface's colour lit regardless of direction.
        diffuse_coeff: Share lit by the light's direction (Lambert).
        specular_coeff: Highlights.
        shadows: Whether objects cast shadows (from the light direction).

    """

    direction: tuple[float, float, float] = (0.4, 0.3, 1.0)
    brightness: float = 1.0
    ambient_coeff: float = 0.6
    diffuse_coeff: float = 0.5
    specular_coeff: float = 0.05
    shadows: bool = True

    def __post_init__(self) -> None:
        if math.hypot(*self.direction) == 0.0:
            raise InvalidInputError("direction", self.direction, "a non-zero vector")
        for name in ("brightness", "ambient_coeff", "diffuse_coeff", "specular_coeff"):
            value = getattr(self, name)
            if not 0.0 <= value <= 2.0:
                raise InvalidInputError(name, value, "in [0, 2]")

    @property
    def colour_rgb(self) -> tuple[float, float, float]:
        """The lamp's colour at full brightness: white."""
        return (1.0, 1.0, 1.0)


@dataclass(frozen=True)
class TintedLighting(Lighting):
    """A light whose lamp has a colour: a scene's drawn light (:mod:`sim.world.looks`).

    Never a camera config's own light, so the camera records datasets and runs keep have the
    fields they always had.

    Attributes:
        tint_rgb: The lamp's colour at full brightness, each channel in [0, 1].

    """

    tint_rgb: tuple[float, float, float] = (1.0, 1.0, 1.0)

    def __post_init__(self) -> None:
        super().__post_init__()
        if len(self.tint_rgb) != 3 or not all(0.0 <= v <= 1.0 for v in self.tint_rgb):
            raise InvalidInputError("tint_rgb", self.tint_rgb, "three channels in [0, 1]")

    @property
    def colour_rgb(self) -> tuple[float, float, float]:
        """The lamp's colour at full brightness: its tint."""
        return self.tint_rgb
