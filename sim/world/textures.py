"""Procedural textures for objects and tables: printed dots, stripes, noise.

A texture is a grey pattern in [:data:`DARKEST`, 1] that PyBullet's renderer multiplies with a
shape's colour, so a textured object keeps its colour and gains a pattern, as a printed sponge
or a striped mug does. Each kind has :data:`VARIANTS` seeded variants, drawn per object; the
files are written once per machine to a cache folder (PyBullet loads textures from files) and
are the same bytes on every machine, so a scene looks the same wherever it is rendered.
"""

from __future__ import annotations

import enum
import os
import tempfile
from pathlib import Path

import numpy as np
from scipy import ndimage

from perception.drawing import write_png
from sim.errors import InvalidInputError

SIZE_PX = 64
"""Side of a texture image [px]: an object spans at most ~25 px of the camera's 128 x 128."""
VARIANTS = 8
"""Seeded variants of each kind (a scene draws one per object)."""
DARKEST = 0.45
"""The pattern's darkest share of the colour: dark enough to see, light enough to keep the hue."""
_TAG = 0x7E7
"""Seeds the patterns apart from every other stream."""
_VERSION = "v1"
"""Bumped when a pattern changes, so a cache never serves an old one."""


class TextureKind(enum.Enum):
    """A pattern printed over a shape's colour (a task file's ``textures`` and table looks)."""

    PLAIN = "plain"  # no pattern: the colour alone
    PRINT = "print"  # scattered dots, as on a printed label or tablecloth
    STRIPES = "stripes"  # parallel bands at a drawn angle and width (wood grain, a striped mug)
    NOISE = "noise"  # smooth mottling (a sponge's pores, linoleum)


def texture_image(kind: TextureKind, variant: int, tiled: bool = False) -> np.ndarray:
    """The pattern as uint8 (SIZE_PX, SIZE_PX, 3) grey; ``tiled`` repeats it finer (a table)."""
    if not isinstance(kind, TextureKind) or kind is TextureKind.PLAIN:
        raise InvalidInputError("texture", kind, "print, stripes or noise")
    if not 0 <= variant < VARIANTS:
        raise InvalidInputError("texture variant", variant, f"an integer in [0, {VARIANTS})")
    rng = np.random.default_rng(np.random.SeedSequence(
        [_TAG, list(TextureKind).index(kind), variant]))
    v, u = np.mgrid[0:SIZE_PX, 0:SIZE_PX].astype(float)
    if kind is TextureKind.STRIPES:
        angle = rng.uniform(0.0, np.pi)
        period = rng.uniform(6.0, 14.0) / (4.0 if tiled else 1.0)
        phase = (u * np.cos(angle) + v * np.sin(angle)) / period
        shade = (np.sin(2 * np.pi * phase) > 0.0).astype(float)
    elif kind is TextureKind.PRINT:
        shade = np.ones((SIZE_PX, SIZE_PX))
        for _ in range(int(rng.integers(10, 20)) * (4 if tiled else 1)):
            cu, cv = rng.uniform(0, SIZE_PX, 2)
            radius = rng.uniform(2.0, 5.0) / (2.0 if tiled else 1.0)
            du = np.minimum(abs(u - cu), SIZE_PX - abs(u - cu))  # wraps: the texture tiles
            dv = np.minimum(abs(v - cv), SIZE_PX - abs(v - cv))
            shade[du**2 + dv**2 <= radius**2] = 0.0
    else:
        noise = ndimage.gaussian_filter(rng.random((SIZE_PX, SIZE_PX)),
                                        sigma=1.5 if tiled else 3.0, mode="wrap")
        shade = (noise - noise.min()) / max(float(np.ptp(noise)), 1e-9)
    grey = np.round(255.0 * (DARKEST + (1.0 - DARKEST) * shade)).astype(np.uint8)
    return np.repeat(grey[:, :, None], 3, axis=2)


def texture_folder() -> Path:
    """Where texture files are cached: ``$GVA_TEXTURES``, else a folder in the temp dir."""
    return Path(os.environ.get("GVA_TEXTURES") or
                Path(tempfile.gettempdir()) / f"gva-textures-{_VERSION}")


def texture_file(kind: TextureKind, variant: int, tiled: bool = False) -> Path:
    """The PNG of a pattern (written on first use; atomic, so parallel workers agree).

    ``PLAIN`` is a white square: a plain finish over a surface whose own texture it replaces.
    """
    name = f"{kind.value}-{variant}{'-tiled' if tiled else ''}.png"
    path = texture_folder() / name
    if path.is_file():
        return path
    path.parent.mkdir(parents=True, exist_ok=True)
    image = np.full((SIZE_PX, SIZE_PX, 3), 255, np.uint8) if kind is TextureKind.PLAIN \
        else texture_image(kind, variant, tiled)
    handle, temporary = tempfile.mkstemp(suffix=".png", dir=path.parent)
    os.close(handle)
    write_png(temporary, image)
    os.replace(temporary, path)
    return path
