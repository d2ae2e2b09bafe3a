"""Drawings with numpy alone: dots, digits, the colormap, attention figures and PNG files."""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import numpy as np
import pytest

from perception.drawing import (
    COLORMAP,
    GAP_PX,
    GLYPHS,
    OUTLINE,
    AttentionRow,
    attention_figure,
    colourise,
    draw_dot,
    draw_number,
    figure_shape,
    head_colour,
    number_size,
    write_png,
)
from perception.interface import InvalidInputError

RED = (255, 0, 0)


def test_a_dots_centre_has_its_colour_and_its_rim_the_outline() -> None:
    canvas = np.full((20, 20, 3), 200, np.uint8)
    draw_dot(canvas, (10.0, 6.0), 3.0, RED)
    assert tuple(canvas[6, 10]) == RED  # (v, u): row 6, column 10
    assert tuple(canvas[6, 13]) == RED  # at the radius
    assert tuple(canvas[6, 14]) == OUTLINE  # in the 1.5 px ring
    assert tuple(canvas[6, 16]) == (200, 200, 200)  # beyond it
    assert tuple(canvas[15, 10]) == (200, 200, 200)


def test_a_dot_at_the_edge_is_clipped_and_a_nan_one_draws_nothing() -> None:
    canvas = np.zeros((8, 8, 3), np.uint8)
    draw_dot(canvas, (0.0, 7.0), 3.0, RED)
    assert tuple(canvas[7, 0]) == RED
    before = canvas.copy()
    draw_dot(canvas, (np.nan, 2.0), 3.0, RED)
    draw_dot(canvas, (-50.0, 2.0), 3.0, RED)
    np.testing.assert_array_equal(canvas, before)


def test_the_ten_digits_draw_distinct_patterns() -> None:
    patterns = set()
    for digit in range(10):
        canvas = np.zeros((7, 5, 3), np.uint8)
        draw_number(canvas, digit, (1, 1), RED, outline=None)
        mask = (canvas == RED).all(axis=-1)
        np.testing.assert_array_equal(mask[1:6, 1:4], GLYPHS[str(digit)])
        patterns.add(mask.tobytes())
    assert len(patterns) == 10


def test_numbers_scale_and_keep_their_digits_apart() -> None:
    assert number_size(7, 1) == (3, 5)
    assert number_size(12, 2) == (14, 10)
    canvas = np.zeros((12, 16, 3), np.uint8)
    draw_number(canvas, 12, (1, 1), RED, scale=2)
    red = (canvas == RED).all(axis=-1)
    np.testing.assert_array_equal(red[1:11, 1:7], np.kron(GLYPHS["1"], np.ones((2, 2), bool)))
    assert not red[:, 7:9].any()  # the gap between the digits
    assert (canvas[0, 2] == OUTLINE).all()  # the outline above the "1"'s top
    with pytest.raises(InvalidInputError, match=r"number = -1 is not allowed: an integer >= 0"):
        draw_number(canvas, -1, (0, 0), RED)


def test_colourise_maps_min_and_max_to_the_colormaps_ends() -> None:
    heatmap = np.array([[0.1, 0.4], [0.7, 0.25]])
    rgb = colourise(heatmap)
    assert rgb.dtype == np.uint8 and rgb.shape == (2, 2, 3)
    assert tuple(rgb[0, 0]) == COLORMAP[0]
    assert tuple(rgb[1, 0]) == COLORMAP[-1]
    brightness = rgb.astype(int).sum(axis=-1)
    assert brightness[0, 0] < brightness[1, 1] < brightness[0, 1] < brightness[1, 0]
    assert (colourise(np.full((3, 3), 0.5)) == COLORMAP[0]).all()
    with pytest.raises(InvalidInputError, match=r"a finite 2-D array"):
        colourise(np.zeros((2, 2, 2)))


def test_attention_figure_has_a_panel_per_heatmap_and_a_row_per_condition() -> None:
    image = np.full((16, 12, 3), 90, np.uint8)
    heatmaps = np.random.default_rng(0).random((2, 4, 3))
    rows = [AttentionRow(np.array([[3.0, 4.0], [8.0, 12.0]]), heatmaps, label=k,
                         highlighted=k == 1) for k in range(3)]
    figure = attention_figure(image, rows, scale=2)
    assert figure.shape == (*figure_shape((16, 12), 2, heads=2, rows=3, labelled=True), 3)
    label_width = number_size(10, 4)[0] + GAP_PX
    assert figure.shape[:2] == (GAP_PX + 3 * (32 + GAP_PX),
                                GAP_PX + label_width + 3 * (24 + GAP_PX))
    left = GAP_PX + label_width
    u, v = 3 * 2 + 0.5, 4 * 2 + 0.5  # point 0 enlarged twice: pixel 3 covers u 6-7
    assert tuple(figure[GAP_PX + round(v), left + round(u)]) == head_colour(0)
    second_row = GAP_PX + 32 + GAP_PX
    assert tuple(figure[second_row + round(v), left + round(u)]) == head_colour(0)


def test_a_figure_without_heatmaps_is_the_image_alone() -> None:
    image = np.zeros((10, 10, 3), np.uint8)
    figure = attention_figure(image, [AttentionRow(np.array([[5.0, 5.0]]))], scale=3)
    assert figure.shape == (2 * GAP_PX + 30, 2 * GAP_PX + 30, 3)


def test_write_png_round_trip(tmp_path: Path) -> None:
    image = np.random.default_rng(0).integers(0, 256, (5, 7, 3), dtype=np.uint8)
    data = write_png(tmp_path / "sub" / "x.png", image).read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    width, height = struct.unpack(">II", data[16:24])
    assert (width, height) == (7, 5)
    start = data.index(b"IDAT") + 4
    length = struct.unpack(">I", data[start - 8:start - 4])[0]
    rows = np.frombuffer(zlib.decompress(data[start:start + length]), np.uint8).reshape(5, -1)
    assert (rows[:, 0] == 0).all()  # filter type "none" on every row
    np.testing.assert_array_equal(rows[:, 1:].reshape(5, 7, 3), image)
    with pytest.raises(InvalidInputError, match=r"image = 'float64 .* uint8 \(H, W, 3\)"):
        write_png(tmp_path / "bad.png", np.zeros((2, 2, 3)))
