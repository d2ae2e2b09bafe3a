"""The focus on a heatmap's densest part (``KqvConfig.focus_window_px``, issue 49)."""

from dataclasses import replace

import pytest
import torch
from user_models import CAMERA, spec

from perception.interface import InvalidInputError, LabelKind
from perception.learning.torch_pieces import coordinate_grid, focus, spatial_expectation
from perception.models.kqv import KqvConfig, KqvModel
from perception.models.kqv_net import FOCUS_WINDOW_PX


def split_map() -> torch.Tensor:
    """A 32 x 32 heatmap (1, 1, h, w): 0.7 of its mass spread over a 6 x 6 object around row
    and column 8, 0.3 on one bright cell (a look-alike's sharp edge) at row and column 24."""
    heatmap = torch.zeros(1, 1, 32, 32)
    heatmap[0, 0, 5:11, 5:11] = 0.7 / 36
    heatmap[0, 0, 24, 24] = 0.3
    return heatmap


def test_focus_reads_the_part_holding_more_mass_not_the_brightest_cell_nor_between():
    heatmap, grid = split_map(), coordinate_grid(32, 32)
    whole = spatial_expectation(heatmap, grid)[0, 0]
    focused = focus(heatmap, box_cells=5, window_cells=6)
    torch.testing.assert_close(focused.sum(), torch.tensor(1.0))
    assert focused[0, 0, 24, 24] == 0  # the look-alike's cell is left out
    centre = (2 * 7.5 + 1) / 32 - 1  # the object's cells 5..10 have their centre at 7.5
    torch.testing.assert_close(spatial_expectation(focused, grid)[0, 0],
                               torch.tensor([centre, centre]))
    assert whole[0] > centre + 0.3  # the whole map's point lies between the two
    brightest = heatmap.flatten().argmax()
    assert brightest == 24 * 32 + 24  # a window around the brightest cell would read the block


def test_focus_leaves_a_map_with_one_object_inside_its_window_as_it_is():
    heatmap = torch.zeros(2, 3, 16, 16)
    heatmap[..., 4:9, 6:10] = torch.rand(2, 3, 5, 4, generator=torch.Generator().manual_seed(0))
    heatmap = heatmap + 1e-9
    heatmap = heatmap / heatmap.sum(dim=(-2, -1), keepdim=True)
    focused = focus(heatmap, box_cells=3, window_cells=8)
    grid = coordinate_grid(16, 16)
    torch.testing.assert_close(spatial_expectation(focused, grid),
                               spatial_expectation(heatmap, grid), atol=1e-6, rtol=0)


def test_the_network_focuses_at_inference_only_and_by_label_kind():
    queries, images = torch.randn(1, 1, 18), torch.rand(1, 3, 64, 64)
    grasp = KqvModel(replace(spec(kind=LabelKind.GRASP_POSE), camera=CAMERA)).network
    assert grasp.focus_cells == (FOCUS_WINDOW_PX // 2, 9)  # stride 2: 24 px, 18 px
    position = KqvModel(spec()).network
    assert position.focus_cells[0] == 0  # the paper's whole heatmap for positions
    grasp.eval()
    inference = grasp.attend(images, queries).heatmaps
    grasp.train()
    training = grasp.attend(images, queries).heatmaps
    assert (inference == 0).any() and (training > 0).all()  # cells outside the window, dropped
    torch.testing.assert_close(inference.sum(), torch.tensor(1.0))
    off = KqvModel(replace(spec(kind=LabelKind.GRASP_POSE), camera=CAMERA),
                   KqvConfig(focus_window_px=0)).network.eval()
    assert (off.attend(images, queries).heatmaps > 0).all()


def test_focus_settings_are_checked():
    with pytest.raises(InvalidInputError, match=r"focus_window_px = -1 is not allowed: None or "
                                                 r"an integer >= 0"):
        KqvConfig(focus_window_px=-1)
    with pytest.raises(InvalidInputError, match=r"focus_box_px = 0 is not allowed: None or an "
                                                 r"integer >= 1"):
        KqvConfig(focus_box_px=0)


def test_read_with_keeps_the_weights_and_changes_only_how_the_heatmap_is_read():
    model = KqvModel(replace(spec(kind=LabelKind.GRASP_POSE), camera=CAMERA))
    whole = model.read_with(focus_window_px=0)
    assert whole.config == replace(model.config, focus_window_px=0)
    assert whole.network.focus_cells[0] == 0 and model.network.focus_cells[0] > 0
    for name, tensor in model.network.state_dict().items():
        torch.testing.assert_close(whole.network.state_dict()[name], tensor)
    images = torch.randint(0, 255, (1, 64, 64, 3), dtype=torch.uint8).numpy()
    queries = model.queries(torch.zeros(1, model.spec.condition_size).numpy())
    assert (whole.attend(images, queries)["heatmaps"] > 0).all()
    assert (model.attend(images, queries)["heatmaps"] == 0).any()
    with pytest.raises(InvalidInputError, match=r"starts = 1 is not allowed: a training setting; "
                                                r"read_with changes only focus_box_px, "
                                                r"focus_window_px"):
        model.read_with(starts=1)


def test_each_camera_states_its_own_focus_and_the_config_overrides_it():
    grasp = replace(spec(kind=LabelKind.GRASP_POSE), camera=CAMERA)  # stride 2 (ray readout)
    stand = replace(grasp, focus_window_px=0, focus_box_px=0)  # a camera with none derived
    assert KqvModel(stand).network.focus_cells == (0, 9)  # the whole heatmap
    wider = replace(grasp, focus_window_px=30, focus_box_px=20)
    assert KqvModel(wider).network.focus_cells == (15, 10)
    assert KqvModel(wider, KqvConfig(focus_window_px=0)).network.focus_cells[0] == 0
    assert KqvModel(stand, KqvConfig(focus_window_px=24, focus_box_px=18)).network.focus_cells \
        == (12, 9)
    position = replace(spec(), focus_window_px=24, focus_box_px=18)
    assert KqvModel(position).network.focus_cells[0] == 0  # positions read whole, as before


def test_focus_training_reads_as_inference_does_once_the_warm_up_is_over():
    from user_models import synthetic_dataset

    from perception.learning.torch_pieces import LabelScaler, images_to_tensor
    from perception.learning.train import Batch

    data = synthetic_dataset(4, kind=LabelKind.GRASP_POSE, seed=1, camera=CAMERA)
    batch = Batch(images_to_tensor(data.images), torch.as_tensor(data.conditions),
                  torch.as_tensor(data.labels))
    for trained_so in (False, True):
        model = KqvModel.for_dataset(data, KqvConfig(focus_training=trained_so, warmup_steps=2))
        model.scaler = model.network.scaler = LabelScaler.fit(data.labels[..., :3])
        model.network.train()
        seen = []
        for _ in range(3):  # step 1 warms up; step 2 reaches the temperature, and the focus
            model.batch_loss(batch)
            out = model.network.attend(batch.images, model.network.queries(batch.conditions))
            seen.append(bool((out.heatmaps == 0).any()))
        assert seen == [False, trained_so, trained_so]
    with pytest.raises(InvalidInputError, match="focus_training = 1 is not allowed"):
        KqvConfig(focus_training=1)
