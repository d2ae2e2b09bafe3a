"""Mirror augmentation: a training sample and its mirror image across the world's xz-plane.

Where the camera sits on that plane (the yumi head camera), the image flipped left to right is
its view of the scene mirrored (y -> -y), and the labels follow: a position's y negated, a grasp
rotation ``R`` turned into ``M R M`` with ``M = diag(1, -1, 1)``, a side condition's left and
right swapped (a one-hot side's entries; a sentence's row, for a model that trains each sentence
as the row of the side it names, by the other side's row). Only for tasks whose collector
allows it (``metadata.extra[MIRROR_FLAG]``, :mod:`sim.tasks.mirror_symmetry`); why and what it
gains: ``docs/decisions/kqv.md#mirror-flip``.
"""

from __future__ import annotations

import numpy as np
import torch
from torch import Tensor

from perception.interface import ConditionKind, InvalidInputError, LabelKind
from perception.learning.learnable import ModelSpec
from perception.learning.train import Batch

MIRROR_FLAG = "mirror_symmetric"
"""The dataset ``extra`` key under which a collector says its samples may be mirrored."""
MIRROR_Y = torch.diag(torch.tensor([1.0, -1.0, 1.0]))
"""The world mirror across the xz-plane, ``M``."""
TOLERANCE_M = 1e-9
SIDE_PAIRS = {"left": "right", "right": "left"}


class Mirror:
    """Mirrors a random half of each training batch, for a model built to ``spec``.

    Args:
        spec: The model's spec; its camera must sit on the world's xz-plane (checked).
        seed: Seeds which samples are mirrored.
        named_rows: For a sentence task over sides: the (k, C) condition row each named side
            trains with (kqv's unit prototypes), in ``spec.condition_choices`` order; a mirrored
            sample gets the other side's row. None for other tasks.

    """

    def __init__(self, spec: ModelSpec, seed: int, named_rows: np.ndarray | None = None) -> None:
        camera = spec.camera
        if camera is None:
            raise InvalidInputError("mirror", True, "False for a dataset that records no camera")
        off_plane = {name: value for name, value in (("position_m", camera.position_m[1]),
                                                     ("target_m", camera.target_m[1]),
                                                     ("up", camera.up[1]))
                     if abs(value) > TOLERANCE_M}
        if off_plane:
            raise InvalidInputError("mirror", True, "False: the camera's y components must be "
                                    f"0 for a left-right mirror (they are {off_plane})")
        p2 = camera.distortion_k1_k2_p1_p2_k3[3]
        if p2 != 0.0:  # p2 (r^2 + 2 x^2) is even in x: the lens's image is not mirror-symmetric
            raise InvalidInputError("mirror", True, "False for a calibration whose lens has a "
                                    f"tangential p2 ({p2}): its image flipped is not the scene "
                                    "mirrored (radial terms and p1 are)")
        ndc = np.asarray(camera.pixels_to_ndc(np.arange(camera.width_px, dtype=float), 0.0)[0])
        source = np.asarray(camera.ndc_to_pixels(-ndc, 0.0)[0])  # column j shows column u(j)
        # PyBullet samples column i at x = 2 i / W - 1, so the mirror of column j is W - j: the
        # flip is off by one column from reversing the array; the first column repeats.
        self.columns = torch.as_tensor(np.clip(np.rint(source), 0, camera.width_px - 1),
                                       dtype=torch.long)  # (W,)
        self.grasps = spec.label_kind is LabelKind.GRASP_POSE
        self.swap: Tensor | None = None
        self.rows: Tensor | None = None  # (k, C) a sentence task's named rows
        names_sides = spec.condition_kind is ConditionKind.SIDE or (
            spec.condition_kind is ConditionKind.TEXT and
            bool(set(spec.condition_choices) & set(SIDE_PAIRS)))  # a type stays in the mirror
        if names_sides and spec.condition_kind is ConditionKind.TEXT:
            if named_rows is None or np.shape(named_rows)[0] != len(spec.condition_choices):
                raise InvalidInputError("mirror", True, "False for a sentence task over sides "
                                        "unless each named side's condition row is given "
                                        "(named_rows)")
            self.rows = torch.as_tensor(np.asarray(named_rows, dtype=np.float32))
        if names_sides:
            choices = list(spec.condition_choices)
            if any(SIDE_PAIRS.get(c) not in choices for c in choices):
                raise InvalidInputError("mirror", True, f"False for side choices {choices} "
                                        "(needs both 'left' and 'right')")
            self.swap = torch.tensor([choices.index(SIDE_PAIRS[c]) for c in choices])
        self.generator = torch.Generator().manual_seed(seed)

    def __call__(self, batch: Batch, flip: Tensor | None = None) -> Batch:
        """The batch with a random half of its samples (or those ``flip`` (B,) marks) mirrored."""
        if flip is None:
            flip = torch.rand(batch.images.shape[0], generator=self.generator) < 0.5  # (B,)
        if not flip.any():
            return batch
        images = batch.images.clone()
        images[flip] = images[flip][..., self.columns.to(images.device)]  # (b, 3, H, W)
        labels = batch.labels.clone()  # (B, q, 3 | 12)
        mirrored = labels[flip]
        mirrored[..., 1] = -mirrored[..., 1]  # y of the position
        if self.grasps:
            m = MIRROR_Y.to(labels)
            mirrored[..., 3:] = (m @ mirrored[..., 3:].unflatten(-1, (3, 3)) @ m).flatten(-2)
        labels[flip] = mirrored
        conditions = batch.conditions.clone()
        if self.rows is not None and self.swap is not None:  # each row by the other side's
            rows = self.rows.to(conditions)
            named = (conditions[flip] @ rows.T).argmax(dim=-1)  # (b,) which side it names
            conditions[flip] = rows[self.swap.to(conditions.device)[named]]
        elif self.swap is not None:
            conditions[flip] = conditions[flip][:, self.swap.to(conditions.device)]
        depths = batch.depths_m
        if depths is not None:  # the depth image flips with the colour one
            depths = depths.clone()
            depths[flip] = depths[flip][..., self.columns.to(depths.device)]  # (b, H, W)
        return batch._replace(images=images, conditions=conditions, labels=labels,
                              depths_m=depths)  # types stay
