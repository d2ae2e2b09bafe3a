"""The torch pieces kqv is built of: the 2-D softmax, spatial expectations, the coordinate grid
and the CoordConv stack (perception/learning/torch_pieces.py)."""

import torch

from perception.learning.torch_pieces import (
    CoordConv,
    CoordConvStack,
    coordinate_grid,
    normalised_to_pixels,
    pixels_to_normalised,
    softmax2d,
    spatial_expectation,
)


def test_softmax2d_sums_to_one_per_head():
    logits = torch.randn(2, 3, 5, 7, generator=torch.Generator().manual_seed(0)) * 10
    for temperature in (0.05, 1.0, 4.0):
        heatmaps = softmax2d(logits, temperature)
        assert heatmaps.shape == (2, 3, 5, 7)
        torch.testing.assert_close(heatmaps.sum(dim=(2, 3)), torch.ones(2, 3))
        assert (heatmaps >= 0).all()
    # a lower temperature sharpens the same logits
    assert softmax2d(logits, 0.1).amax() >= softmax2d(logits, 1.0).amax()


def test_one_hot_heatmap_extracts_that_cells_feature_and_coordinates():
    values = torch.randn(1, 4, 6, 8, generator=torch.Generator().manual_seed(1))
    heatmaps = torch.zeros(1, 2, 6, 8)
    heatmaps[0, 0, 2, 5] = 1.0  # row 2, column 5
    heatmaps[0, 1, 0, 0] = 1.0
    features = spatial_expectation(heatmaps, values)
    torch.testing.assert_close(features[0, 0], values[0, :, 2, 5])
    torch.testing.assert_close(features[0, 1], values[0, :, 0, 0])
    coords = spatial_expectation(heatmaps, coordinate_grid(6, 8))
    expected = torch.tensor([(2 * 5 + 1) / 8 - 1, (2 * 2 + 1) / 6 - 1])  # (x, y) of the centre
    torch.testing.assert_close(coords[0, 0], expected)
    # cell (row 2, column 5) of a 6 x 8 map over a 96 x 128 image: pixels u 80-95, v 32-47
    pixels = normalised_to_pixels(coords, 96, 128)
    torch.testing.assert_close(pixels[0, 0], torch.tensor([87.5, 39.5]))
    torch.testing.assert_close(pixels_to_normalised(pixels, 96, 128), coords)


def test_coordinate_grid_spans_minus_one_to_one_at_the_edges():
    grid = coordinate_grid(4, 4)
    assert grid.shape == (2, 4, 4)
    assert grid[0, 0, 0] == -0.75 and grid[0, 0, -1] == 0.75  # x: left to right
    assert grid[1, 0, 0] == -0.75 and grid[1, -1, 0] == 0.75  # y: top to bottom
    edges = normalised_to_pixels(torch.tensor([[-1.0, -1.0], [1.0, 1.0]]), 64, 64)
    torch.testing.assert_close(edges, torch.tensor([[-0.5, -0.5], [63.5, 63.5]]))


def test_a_coordconv_stack_is_its_layers_run_one_by_one_forward_and_back():
    # The stack adds each layer's coordinates as a share of the next layer's output instead of
    # concatenating them to every map: the same sums, zero padding at the borders included.
    torch.manual_seed(0)
    layers = [CoordConv(4, 6, 5, 2), CoordConv(8, 6, 3, 1), CoordConv(8, 6, 3, 1, dilation=2),
              CoordConv(8, 5, 3, 2, activation=False)]
    stack, one_by_one = CoordConvStack(*layers), torch.nn.Sequential(*layers)
    images = torch.rand(3, 4, 20, 24).contiguous(memory_format=torch.channels_last)
    got, want = stack(images), one_by_one(images)
    assert got.shape == (3, 5 + 2, 5, 6)
    torch.testing.assert_close(got, want, rtol=1e-5, atol=1e-6)
    shared = list(stack.parameters())  # the same layers, so the same parameters
    for mine, theirs in zip(torch.autograd.grad(got.square().sum(), shared),
                            torch.autograd.grad(want.square().sum(), shared), strict=True):
        torch.testing.assert_close(mine, theirs, rtol=1e-4, atol=1e-5)
    # the parameters keep an nn.Sequential's names: checkpoints from before still load
    assert list(stack.state_dict()) == list(one_by_one.state_dict())
