"""Drawings of what a model attends to, like the paper's Fig. 5, with numpy alone; PNG files.

An attention figure shows one image, enlarged, with each attention point as a filled dot (one
colour per head, a dark outline) and the head's number beside it; beside the image, each head's
heatmap (upsampled to the image, coloured from dark to bright) with the same dot. A top-down
model gets one row per condition choice, labelled with the choice's index, so the figure shows
the attention move as the condition changes::

    rows = [AttentionRow(p.attention_px, p.heatmaps, label=k) for k, p in enumerate(predictions)]
    write_png("attention.png", attention_figure(image, rows, scale=3))

Digits come from a 3 x 5 bitmap font drawn here: no imaging library is needed.
"""

from __future__ import annotations

import struct
import zlib
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from perception.interface import InvalidInputError

Colour = tuple[int, int, int]

BACKGROUND: Colour = (30, 30, 30)
OUTLINE: Colour = (0, 0, 0)
LABEL: Colour = (255, 255, 255)  # a row's label when it is the sample's own condition
DIMMED_LABEL: Colour = (130, 130, 130)  # the other rows' labels
HEAD_COLOURS: tuple[Colour, ...] = (  # bright and far apart, so a dot shows on wood and objects
    (255, 60, 60), (60, 210, 255), (255, 225, 40), (90, 255, 90),
    (255, 100, 255), (255, 150, 30), (160, 130, 255), (255, 255, 255),
)
COLORMAP: tuple[Colour, ...] = (  # an inferno-like ramp: low attention dark, high bright
    (0, 0, 4), (87, 16, 110), (188, 55, 84), (249, 142, 9), (252, 255, 164),
)
HEATMAP_COLUMNS = 4  # heatmap panels per line beside the image; more heads wrap to a new line
GAP_PX = 4  # between panels and around the figure

DIGIT_ROWS, DIGIT_COLUMNS = 5, 3
_FONT = {  # 3 x 5 glyphs, row by row
    "0": ("111", "101", "101", "101", "111"),
    "1": ("010", "110", "010", "010", "111"),
    "2": ("111", "001", "111", "100", "111"),
    "3": ("111", "001", "111", "001", "111"),
    "4": ("101", "101", "111", "001", "001"),
    "5": ("111", "100", "111", "001", "111"),
    "6": ("111", "100", "111", "101", "111"),
    "7": ("111", "001", "001", "010", "010"),
    "8": ("111", "101", "111", "101", "111"),
    "9": ("111", "101", "111", "001", "111"),
}
GLYPHS = {digit: np.array([[c == "1" for c in row] for row in rows])
          for digit, rows in _FONT.items()}
"""Each digit as a (5, 3) bool mask, True where it is drawn."""


@dataclass(frozen=True)
class AttentionRow:
    """One row of an attention figure: what a model attended to under one condition.

    Args:
        points_px: (p, 2) attention points (u right, v down) in the image's pixels.
        heatmaps: (p, h, w) heatmaps, one panel each; None draws the image panel only.
        label: A number drawn at the row's left (the condition's index); None: no label.
        highlighted: Draw the label bright (the sample's own condition), else dimmed.

    """

    points_px: np.ndarray
    heatmaps: np.ndarray | None = None
    label: int | None = None
    highlighted: bool = True


CAPTION_LINE_PX = 14
"""Height of one caption line (Pillow's default font is 11 px high)."""
CAPTION_BACKGROUND, CAPTION_TEXT = (20, 20, 20), (235, 235, 235)


def head_colour(head: int) -> Colour:
    """The colour of attention head ``head`` (the palette repeats after eight heads)."""
    return HEAD_COLOURS[head % len(HEAD_COLOURS)]


def draw_dot(canvas: np.ndarray, centre_uv: Sequence[float], radius_px: float,
             colour: Colour, outline: Colour | None = OUTLINE, outline_px: float = 1.5) -> None:
    """Draws a filled dot centred at pixel ``centre_uv`` (u right, v down) into ``canvas``.

    Pixels within ``radius_px`` of the centre take ``colour``; a ring ``outline_px`` wide
    around it takes ``outline``. The part outside the canvas is clipped; a non-finite centre
    draws nothing.
    """
    u, v = (float(c) for c in centre_uv)
    if not (np.isfinite(u) and np.isfinite(v)):
        return
    reach = radius_px + (outline_px if outline is not None else 0.0)
    height, width = canvas.shape[:2]
    v0, v1 = max(int(np.floor(v - reach)), 0), min(int(np.ceil(v + reach)) + 1, height)
    u0, u1 = max(int(np.floor(u - reach)), 0), min(int(np.ceil(u + reach)) + 1, width)
    if v0 >= v1 or u0 >= u1:
        return
    rows, columns = np.mgrid[v0:v1, u0:u1]
    distance = np.hypot(rows - v, columns - u)  # (v1 - v0, u1 - u0) [px]
    window = canvas[v0:v1, u0:u1]
    if outline is not None:
        window[distance <= reach] = outline
    window[distance <= radius_px] = colour


def number_size(number: int, scale: int = 1) -> tuple[int, int]:
    """(width, height) in pixels that :func:`draw_number` covers, outline excluded."""
    digits = len(str(number))
    return (digits * (DIGIT_COLUMNS + 1) - 1) * scale, DIGIT_ROWS * scale


def draw_number(canvas: np.ndarray, number: int, top_left_uv: Sequence[int], colour: Colour,
                scale: int = 1, outline: Colour | None = OUTLINE) -> None:
    """Draws the non-negative integer ``number`` with its top-left corner at ``top_left_uv``.

    Each digit is the 3 x 5 glyph enlarged ``scale`` times, one glyph column apart; with an
    ``outline``, a 1-pixel border of that colour keeps it legible on any background.
    """
    if not isinstance(number, int | np.integer) or number < 0:
        raise InvalidInputError("number", number, "an integer >= 0")
    if not isinstance(scale, int | np.integer) or scale < 1:
        raise InvalidInputError("scale", scale, "an integer >= 1")
    width, height = number_size(int(number), int(scale))
    mask = np.zeros((height, width), dtype=bool)
    for k, digit in enumerate(str(int(number))):
        glyph = np.kron(GLYPHS[digit], np.ones((scale, scale), dtype=bool))
        left = k * (DIGIT_COLUMNS + 1) * scale
        mask[:, left:left + DIGIT_COLUMNS * scale] = glyph
    u, v = int(top_left_uv[0]), int(top_left_uv[1])
    if outline is not None:
        grown = np.zeros((height + 2, width + 2), dtype=bool)
        for dv in range(3):
            for du in range(3):
                grown[dv:dv + height, du:du + width] |= mask
        _paint(canvas, grown, (u - 1, v - 1), outline)
    _paint(canvas, mask, (u, v), colour)


def _paint(canvas: np.ndarray, mask: np.ndarray, top_left_uv: tuple[int, int],
           colour: Colour) -> None:
    """Sets ``canvas`` pixels under ``mask`` (placed at ``top_left_uv``) to ``colour``, clipped."""
    u, v = top_left_uv
    height, width = canvas.shape[:2]
    v0, u0 = max(v, 0), max(u, 0)
    v1, u1 = min(v + mask.shape[0], height), min(u + mask.shape[1], width)
    if v0 < v1 and u0 < u1:
        canvas[v0:v1, u0:u1][mask[v0 - v:v1 - v, u0 - u:u1 - u]] = colour


def colourise(heatmap: np.ndarray) -> np.ndarray:
    """A heatmap (h, w) coloured as uint8 RGB (h, w, 3) with :data:`COLORMAP`.

    Its minimum takes the colormap's first colour, its maximum the last, linear in between; a
    constant heatmap is all the first colour.
    """
    values = np.asarray(heatmap, dtype=np.float64)
    if values.ndim != 2 or not np.all(np.isfinite(values)):
        raise InvalidInputError("heatmap", f"{values.dtype} {values.shape}",
                                "a finite 2-D array (h, w)")
    low, span = values.min(), np.ptp(values)
    unit = (values - low) / span if span > 0 else np.zeros_like(values)  # (h, w) in [0, 1]
    stops = np.linspace(0.0, 1.0, len(COLORMAP))
    ramp = np.array(COLORMAP, dtype=np.float64)  # (K, 3)
    rgb = np.stack([np.interp(unit, stops, ramp[:, c]) for c in range(3)], axis=-1)
    return np.rint(rgb).astype(np.uint8)  # (h, w, 3)


def enlarge(image: np.ndarray, height_px: int, width_px: int) -> np.ndarray:
    """``image`` (h, w, ...) resized to (height_px, width_px, ...) by nearest neighbour."""
    rows = np.arange(height_px) * image.shape[0] // height_px
    columns = np.arange(width_px) * image.shape[1] // width_px
    return image[rows[:, None], columns[None, :]]


def scaled_point(point_px: Sequence[float], scale: int) -> tuple[float, float]:
    """Where image pixel coordinates (u, v) land in the image enlarged ``scale`` times.

    Pixel centres sit on integers, so pixel ``u`` covers ``[u S, (u + 1) S)`` once enlarged.
    """
    return ((point_px[0] + 0.5) * scale - 0.5, (point_px[1] + 0.5) * scale - 0.5)


def draw_points(panel: np.ndarray, points_px: np.ndarray, scale: int,
                heads: Sequence[int] | None = None) -> None:
    """Draws attention points (p, 2) in image pixels onto ``panel``, the image enlarged.

    Each point is a dot in its head's colour with the head's number beside it; ``heads`` gives
    the points' head numbers (by default 0, 1, ...).
    """
    radius = max(2.0, 2.0 * scale)
    digit_scale = max(1, scale)
    _, digit_height = number_size(0, digit_scale)
    for k, point in enumerate(np.asarray(points_px, dtype=np.float64)):
        head = k if heads is None else heads[k]
        u, v = scaled_point(point, scale)
        if not (np.isfinite(u) and np.isfinite(v)):
            continue
        draw_dot(panel, (u, v), radius, head_colour(head))
        width, _ = number_size(head, digit_scale)
        left = u + radius + 3  # to the right of the dot; to its left near the panel's edge
        if left + width > panel.shape[1]:
            left = u - radius - 3 - width
        draw_number(panel, head, (round(left), round(v - digit_height / 2)), head_colour(head),
                    digit_scale)


def attention_figure(image: np.ndarray, rows: Sequence[AttentionRow], scale: int = 3,
                     caption: Sequence[str] = ()) -> np.ndarray:
    """The attention figure (H', W', 3) uint8 of ``image`` (H, W, 3), one line per row.

    Layout (see :func:`figure_shape`): a label strip when any row has a label, the image
    panel, then the heatmap panels, :data:`HEATMAP_COLUMNS` to a line; every panel is the
    image's size times ``scale``, :data:`GAP_PX` apart. ``caption`` lines (the sentence each
    row was asked, say) are written above it (:func:`with_caption`).
    """
    image = np.asarray(image)
    if image.dtype != np.uint8 or image.ndim != 3 or image.shape[2] != 3:
        raise InvalidInputError("image", f"{image.dtype} {image.shape}", "uint8 (H, W, 3)")
    if not isinstance(scale, int) or scale < 1:
        raise InvalidInputError("scale", scale, "an integer >= 1")
    if not rows:
        raise InvalidInputError("rows", "none", "at least one AttentionRow")
    height, width = image.shape[0] * scale, image.shape[1] * scale
    heads = max(_heatmap_count(row) for row in rows)
    labelled = any(row.label is not None for row in rows)
    figure = np.empty((*figure_shape(image.shape[:2], scale, heads, len(rows), labelled), 3),
                      dtype=np.uint8)
    figure[:] = BACKGROUND
    label_scale = 2 * scale
    label_width = _label_width(scale) if labelled else 0
    block = _lines(heads) * (height + GAP_PX)  # one row's height, its gap included
    enlarged = enlarge(image, height, width)
    for r, row in enumerate(rows):
        top = GAP_PX + r * block
        if row.label is not None:
            colour = LABEL if row.highlighted else DIMMED_LABEL
            number_height = number_size(row.label, label_scale)[1]
            draw_number(figure, row.label, (GAP_PX, top + (height - number_height) // 2),
                        colour, label_scale, outline=None)
        left = GAP_PX + label_width
        panel = enlarged.copy()
        draw_points(panel, row.points_px, scale)
        figure[top:top + height, left:left + width] = panel
        heatmaps = () if row.heatmaps is None else row.heatmaps
        for k, heatmap in enumerate(heatmaps):
            line, column = divmod(k, HEATMAP_COLUMNS)
            panel = enlarge(colourise(heatmap), height, width)
            if k < len(row.points_px):
                draw_points(panel, row.points_px[k:k + 1], scale, heads=[k])
            draw_number(panel, k, (3, 3), head_colour(k), max(1, scale))
            v0 = top + line * (height + GAP_PX)
            u0 = left + (1 + column) * (width + GAP_PX)
            figure[v0:v0 + height, u0:u0 + width] = panel
    return with_caption(figure, caption) if caption else figure


def with_caption(image: np.ndarray, lines: Sequence[str]) -> np.ndarray:
    """``image`` under a dark strip holding ``lines`` of text, :data:`CAPTION_LINE_PX` each.

    Letters are Pillow's built-in bitmap font (Pillow is imported here only: digits alone
    need no imaging library); a line too long for the width is cut with an ellipsis.
    """
    from PIL import Image, ImageDraw

    width = image.shape[1]
    strip = Image.new("RGB", (width, CAPTION_LINE_PX * len(lines)), CAPTION_BACKGROUND)
    draw = ImageDraw.Draw(strip)
    for k, line in enumerate(lines):
        text = line
        while text and draw.textlength(text) > width - 6:
            text = text[:-2] + "…" if len(text) > 2 else ""
        draw.text((3, 1 + k * CAPTION_LINE_PX), text, fill=CAPTION_TEXT)
    return np.concatenate([np.asarray(strip, dtype=np.uint8), image], axis=0)


def figure_shape(image_hw: tuple[int, int], scale: int, heads: int, rows: int,
                 labelled: bool) -> tuple[int, int]:
    """(height, width) in pixels of an :func:`attention_figure` with ``heads`` heatmaps per row.

    Each row is the image panel plus ``heads`` heatmap panels, :data:`HEATMAP_COLUMNS` to a
    line; a labelled figure starts with a strip for the row numbers.
    """
    height, width = image_hw[0] * scale, image_hw[1] * scale
    columns = 1 + min(heads, HEATMAP_COLUMNS)
    label_width = _label_width(scale) if labelled else 0
    return (GAP_PX + rows * _lines(heads) * (height + GAP_PX),
            GAP_PX + label_width + columns * (width + GAP_PX))


def _label_width(scale: int) -> int:
    """Width of the label strip: two digits at twice ``scale``, plus a gap."""
    return number_size(10, 2 * scale)[0] + GAP_PX


def _lines(heads: int) -> int:
    return max(1, -(-heads // HEATMAP_COLUMNS))


def _heatmap_count(row: AttentionRow) -> int:
    if row.heatmaps is None:
        return 0
    if np.ndim(row.heatmaps) != 3:
        raise InvalidInputError("heatmaps", np.shape(row.heatmaps), "shape (p, h, w)")
    return len(row.heatmaps)


def write_png(path: str | Path, image: np.ndarray) -> Path:
    """Write a uint8 (H, W, 3) RGB image as a PNG file (zlib only, no imaging library)."""
    array = np.asarray(image)
    if array.dtype != np.uint8 or array.ndim != 3 or array.shape[2] != 3:
        raise InvalidInputError("image", f"{array.dtype} {array.shape}", "uint8 (H, W, 3)")
    height, width = array.shape[:2]
    rows = np.hstack([np.zeros((height, 1), np.uint8), array.reshape(height, width * 3)])

    def chunk(kind: bytes, data: bytes) -> bytes:
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))

    header = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)  # 8-bit RGB
    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header)
    png += chunk(b"IDAT", zlib.compress(rows.tobytes(), 6)) + chunk(b"IEND", b"")
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_bytes(png)
    return out
