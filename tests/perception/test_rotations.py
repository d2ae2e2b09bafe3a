"""Grasp rotation codes: 6-D and axis-line, their losses and the half-turn twin."""

import numpy as np
import pytest
import torch
from user_models import DOWN, rot_z

from perception.interface import InvalidInputError
from perception.labels import check_rotations
from perception.learning.rotations import (
    CLOSING_REFERENCE,
    FLIP_Z,
    axis_line_from_raw,
    axis_line_loss,
    axis_line_of,
    decode_rotation,
    rotation_from_6d,
    rotation_from_axis_line,
    rotation_size,
    symmetric_angle_rad,
    symmetric_chordal_loss,
)


def random_rotations(count, seed):
    return rotation_from_6d(torch.randn(count, 6, generator=torch.Generator().manual_seed(seed)))


def test_rotation_from_6d_is_proper_and_keeps_the_first_column_direction():
    six = torch.randn(50, 6, generator=torch.Generator().manual_seed(2))
    rotation = rotation_from_6d(six).double().numpy()
    check_rotations("rotation", rotation)
    first = six[:, :3].numpy() / np.linalg.norm(six[:, :3].numpy(), axis=1, keepdims=True)
    np.testing.assert_allclose(rotation[:, :, 0], first, atol=1e-5)


def test_rotation_loss_and_angle_ignore_the_gripper_half_turn():
    target = torch.tensor(rot_z(0.3) @ DOWN, dtype=torch.float32)
    flipped = target @ torch.diag(torch.tensor([-1.0, -1.0, 1.0]))
    assert symmetric_chordal_loss(flipped, target) < 1e-10
    assert symmetric_chordal_loss(target, target) < 1e-10
    other = torch.tensor(rot_z(0.3 + np.pi / 2) @ DOWN, dtype=torch.float32)
    assert symmetric_chordal_loss(other, target) == pytest.approx(4.0, abs=1e-5)  # 90 degrees
    angle = symmetric_angle_rad(flipped.double().numpy(), target.double().numpy())
    assert angle == pytest.approx(0.0, abs=1e-6)
    assert symmetric_angle_rad(rot_z(0.5) @ DOWN, rot_z(0.3) @ DOWN) == pytest.approx(0.2)


def test_the_axis_line_code_is_the_same_for_a_grasp_and_its_twin_and_decodes_back():
    rotations = random_rotations(200, seed=3)
    codes = axis_line_of(rotations)
    torch.testing.assert_close(axis_line_of(rotations @ FLIP_Z), codes)
    assert axis_line_loss(codes, rotations @ FLIP_Z).abs().max() < 1e-10
    # the 9 numbers a head gives for that code: z, then the line tensor's 6 entries
    lines = codes[..., 1:]
    raw = torch.cat([codes[..., 0], lines[:, [0, 1, 2, 0, 0, 1], [0, 1, 2, 1, 2, 2]]], dim=-1)
    torch.testing.assert_close(axis_line_from_raw(raw), codes)
    decoded, decoded_codes = decode_rotation(raw, "axis-line")
    check_rotations("decoded", decoded.double().numpy())
    angles = symmetric_angle_rad(decoded.double().numpy(), rotations.double().numpy())
    assert angles.max() < 1e-3  # the grasp itself or its twin
    reference = torch.tensor(CLOSING_REFERENCE)
    assert (decoded[:, :, 0] @ reference >= 0).all()  # the twin whose x points back-left
    torch.testing.assert_close(decoded_codes, codes)


def test_a_turn_moves_the_decoded_rotation_and_its_code_alike():
    raw = torch.randn(20, 9, generator=torch.Generator().manual_seed(4))
    turn = torch.tensor(rot_z(0.7), dtype=torch.float32).expand(20, 3, 3)
    local, local_codes = decode_rotation(raw, "axis-line")
    turned, turned_codes = decode_rotation(raw, "axis-line", turn)
    torch.testing.assert_close(turned, turn @ local)
    torch.testing.assert_close(turned_codes[..., 0], (turn @ local_codes[..., :1])[..., 0])
    torch.testing.assert_close(turned_codes[..., 1:],
                               turn @ local_codes[..., 1:] @ turn.transpose(-1, -2))


@pytest.mark.parametrize(("axis", "factor"), [(0, 1.0), (1, 3.0), (2, 2.0)])
def test_a_small_turn_costs_what_the_chordal_loss_charges_within_a_factor_of_two(axis, factor):
    target = torch.tensor(rot_z(0.2) @ DOWN, dtype=torch.float64)
    angle = 0.01
    turn = torch.zeros(3, dtype=torch.float64)
    turn[axis] = angle
    small = torch.linalg.matrix_exp(torch.tensor([[0, -turn[2], turn[1]], [turn[2], 0, -turn[0]],
                                                  [-turn[1], turn[0], 0]], dtype=torch.float64))
    turned = target @ small  # turned about the TCP's own x, y or z axis
    assert axis_line_loss(axis_line_of(turned), target).item() == \
        pytest.approx(factor * angle ** 2, rel=0.01)
    assert symmetric_chordal_loss(turned, target).item() == pytest.approx(2 * angle ** 2, rel=0.01)


@pytest.mark.parametrize(("code", "learns_the_seam"), [("6d", False), ("axis-line", True)])
def test_only_the_axis_line_head_learns_a_look_that_repeats_after_a_half_turn(code,
                                                                             learns_the_seam):
    # A sponge-like object: what the network sees of its yaw θ repeats after a half turn
    # (cos 2θ, sin 2θ), and its canonical grasp's closing axis points to the left, so the label
    # switches twin where the axis is straight ahead. A 6-D head must jump there, a continuous
    # one cannot: it averages the twins; the axis-line code is the same on both sides.
    torch.manual_seed(0)
    yaw = torch.linspace(0, 2 * np.pi, 181)[:-1]
    looks = torch.stack([torch.cos(2 * yaw), torch.sin(2 * yaw)], dim=-1)  # (N, 2)
    labels = torch.tensor(np.stack([rot_z(float(t)) @ DOWN for t in yaw]), dtype=torch.float32)
    left = labels[:, 1, 0] < 0  # closing axis x = (cos θ, -sin θ): pointing right -> flip
    labels[left] = labels[left] @ FLIP_Z
    head = torch.nn.Sequential(torch.nn.Linear(2, 64), torch.nn.Tanh(),
                               torch.nn.Linear(64, rotation_size(code)))
    optimiser = torch.optim.Adam(head.parameters(), lr=1e-2)
    for _ in range(400):
        rotations, codes = decode_rotation(head(looks), code)
        loss = symmetric_chordal_loss(rotations, labels) if codes is None else \
            axis_line_loss(codes, labels)
        optimiser.zero_grad()
        loss.mean().backward()
        optimiser.step()
    with torch.no_grad():
        rotations, _ = decode_rotation(head(looks), code)
    worst_deg = np.degrees(symmetric_angle_rad(rotations.double().numpy(),
                                               labels.double().numpy()).max())
    assert (worst_deg < 5.0) == learns_the_seam, f"{code}: worst {worst_deg:.1f} degrees"


def test_an_unknown_rotation_code_is_named():
    with pytest.raises(InvalidInputError, match=r"rotation = 'quaternion' .*'6d', 'axis-line'"):
        rotation_size("quaternion")


def test_a_line_tensor_negative_in_the_plane_still_decodes_to_a_rotation():
    """An untrained head's six line numbers may be any symmetric matrix, negative ones too."""
    raw = torch.randn(256, 9, generator=torch.Generator().manual_seed(3))
    raw[:, 3:6] = -raw[:, 3:6].abs() - 1.0  # a negative diagonal: negative definite, mostly
    rotation = rotation_from_axis_line(axis_line_from_raw(raw)).double()
    eye = torch.eye(3, dtype=torch.float64).expand(256, 3, 3)
    torch.testing.assert_close(rotation @ rotation.transpose(-1, -2), eye, atol=1e-5, rtol=0)
    torch.testing.assert_close(torch.linalg.det(rotation), torch.ones(256, dtype=torch.float64),
                               atol=1e-5, rtol=0)
    code = axis_line_from_raw(raw).double()
    torch.testing.assert_close(rotation[:, :, 2], code[:, :, 0])  # z as given
    x, y = rotation[:, :, 0], rotation[:, :, 1]  # x: the plane's principal axis, y the other
    along = torch.einsum("bi,bij,bj->b", x, code[:, :, 1:], x)
    across = torch.einsum("bi,bij,bj->b", y, code[:, :, 1:], y)
    assert bool((along >= across - 1e-4).all())
