"""The KQV attention model's hyper-parameters, each with what it was measured to do.

:class:`KqvConfig` is what a ``kqv`` checkpoint's ``config.json`` keeps as ``hyperparameters``;
import it from :mod:`perception.models.kqv` or from here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from perception.interface import InvalidInputError
from perception.learnable import check_choices
from perception.models.rotations import ROTATION_CODES

QUERY_MODES = ("auto", "base", "conditioned", "conditioned+base")
READOUTS = ("auto", "mlp", "ray")
INPUT_NORMS = ("auto", "fixed", "per-image")


@dataclass(frozen=True)
class KqvConfig:
    """Hyper-parameters of the KQV attention model.

    Args:
        channels: Output channels of the first two conv layers of FCN1 and of FCN2; few in the
            first (it runs at the finest resolution), more in the second.
        key_dim: Ck, the Key's learned channels; Keys and Queries have Ck + 2 entries (the two
            coordinate channels ride along, so a Query can prefer a place as well as a look).
        value_dim: Cv, the Feature Value's channels (the length of ``a_feat``).
        input_norm: How images are scaled before the FCNs. ``"fixed"``: ``(image - 0.5) / 0.25``.
            ``"per-image"``: each image's colour channels standardised by their own mean and
            spread, so a darker room (PyBullet scales every pixel alike: brightness 0.5 halves
            them) looks like the bright one the demonstrations were recorded in; training's
            brightness augmentation (0.7-1.3) does not reach that far (yumi trials under
            brightness 0.5 with fixed scaling: 1, 0, 1, 0 of 30). ``"auto"``: per-image for
            grasp-pose labels (the robot's trials), fixed for positions (the paper's simulator
            experiment, Table II, as measured).
        stride: Downsampling from image to heatmap, 1, 2 or 4 (stride 2 in the first one or two
            layers of each FCN): 4 turns 128 x 128 images into 32 x 32 heatmaps. None: 2 with
            the ray readout, 4 otherwise. A picked object needs its point to within a pixel or
            two (the spray bottle's 6 mm to spare per finger are 1.2 px at the yumi camera's
            2 px per cm); a 64 x 64 heatmap halves the errors of a 32 x 32 one at 2.2 times the
            training time (yumi ``multiple``, 20 demonstrations, 100 untrained scenes, with the
            point loss: bottle 1.05 -> 0.50 cm mean, grasps more than 8.5 mm off along the
            closing axis 33 -> 5 of 100). The paper's simulator experiment keeps 4.
        similarity: How a Query meets the Key at each cell. ``"dot"``: the paper's scaled dot
            product K · Q / sqrt(hw). ``"cosine"``: K and Q normalised to unit length first, so
            the logits lie in [-1, 1] before the temperature. With the unbounded dot product the
            network sharpens each heatmap onto a single cell (measured: 95 % of the mass), so
            ``a_coord`` snaps to the 32 x 32 cell grid (4 px, about 2 cm on the table) and the
            gradient that could refine it vanishes; bounded logits keep a heatmap a few cells
            wide, and its expectation falls between cells (validation error 2.7 -> 1.4 cm on
            the yumi ``single`` task, 20 training scenes).
        temperature: Divides the logits before the 2-D softmax: with cosine similarity it sets
            how peaked a heatmap can get (1 / temperature between best and worst match). 0.1
            was best on validation scenes (yumi ``single``: 0.02 -> 1.75 cm, 0.05 -> 1.74,
            0.1 -> 1.37-1.51 over three seeds, 0.2 -> 1.45-2.07, 0.3 -> 1.67).
        warmup_temperature: The temperature at the first training step; it falls linearly to
            ``temperature`` over ``warmup_steps`` steps, then stays there (inference always uses
            ``temperature``). Trained at 0.1 from the start, a heatmap can settle on one place
            within a few steps, where its softmax saturates and no gradient moves it again: a
            fixed spot or a spread-out map. Soft heatmaps first let every Query find its objects
            (paper-sim validation, 10 cells at 20 and 100 scenes over two seeds: failures above
            5 cm 3 -> 2, ``single`` 100 scenes 7.6 -> 2.0 cm, ``selected-type`` 20 scenes
            1.35/1.55 -> 1.07/1.20 cm).
        warmup_steps: Length of that warm-up, in optimiser steps (0: none).
        starts: Initialisations tried on a model's first fit; each trains ``start_steps``
            steps, the best by then (see ``start_holdout``) goes on for the rest of the
            steps and the others are dropped. Even warmed up, a start now and then leaves a
            Query's heatmap spread over the whole image, where the loss sits on a plateau for
            hundreds of steps (paper-sim ``single`` 100 scenes, seed 1: 0.55 until step 700,
            10.0 cm). By the end of the temperature warm-up a good start has its loss a decade
            lower than such a one, so the choice is cheap: 1: one start, as before. The point
            loss does not make them needless: yumi ``multiple`` with it, one start against
            three, bottle grasp error 0.94 against 0.50 cm.
        start_holdout: Fraction of the training scenes the starts are compared on: held out of
            their ``start_steps`` steps, then trained on with the rest. A start that memorised
            its scenes fits them best, so a choice by training loss keeps exactly such a start;
            compared on scenes none of them saw, the one that found the objects wins
            (``docs/decisions/every-condition.md``). 0: the lowest training loss, as before.
        start_steps: Steps each start trains before the choice (they count towards the total).
            300, the warm-up's length: chosen at step 150, mid warm-up, a start still on its way
            down was kept over one that would have worked (``selected-type`` 20 scenes, seed 1:
            13.7 cm; chosen at step 300: 1.3 cm). A dataset on which every start stalls stays
            out of reach (``single`` 100 scenes, seed 1: 8.4 cm).
        query_mode: ``"base"`` (learned vectors), ``"conditioned"`` (MLP of the one-hot
            condition), ``"conditioned+base"`` (their sum) or ``"auto"``: base without a
            condition, conditioned+base for an object-type condition, conditioned for a side.
            A type names a look: with a shared Base Query, and the condition's MLP starting at
            zero, every condition first attends to objects, then learns to prefer its own type
            (1.2-1.9 cm and 96-100 % of scenes attended right over four seeds; paper-sim
            ``selected-type``, 20 scenes); Conditioned Queries alone spread each heatmap over
            all three objects and the head memorises the mixtures (17.5-21.7 cm, 0 %). A side
            names a place among two look-alike objects, so a shared Base Query starts every
            condition split between them, and the head memorises the training scenes instead
            (train 0.5-0.7 cm, validation 8.4-12.0 cm, 0 % right); Conditioned Queries start
            apart and each takes its side (1.2, 1.7, 3.8 cm and 92-100 % over three seeds;
            ``selected-position``, 20 scenes).
        head_features: Whether the head MLP reads ``a_feat`` besides ``a_coord``; None: for
            grasp labels (orientation and grasp offset depend on what the object looks like) and
            the ray readout (its heights come from it); coordinates only for positions read by
            the MLP, as in the paper's simulator experiment: with 20 scenes a head that reads
            features memorises them (validation 3.4 cm, against 1.4 cm from coordinates only;
            yumi ``single``, object positions).
        readout: How the head turns an attention point into a target. ``"mlp"``, the paper's:
            an MLP maps ``a_coord`` (and ``a_feat``) to the target, learning the camera's
            image-to-world mapping from the samples. ``"ray"``: the point is read through the
            dataset's calibrated camera; the MLP, from ``a_feat`` alone, gives the height at which
            the point's ray meets the target, a small offset and the grasp's rotation, both in
            the frame turned toward the target's bearing from the robot base at the world origin
            (a grasp approached from the base looks the same from every bearing). Nothing about
            where in the image a target is needs learning then, so 20 demonstrations generalise
            (yumi ``single``, 20 demonstrations, grasp position error on 100 untrained scenes:
            MLP 2.27 cm mean, 2.08 median; ray 0.86 and 0.72; ``make demo`` picks 15/30 -> 28/30).
            ``"auto"``: ray for grasp-pose labels when the dataset records its camera, MLP
            otherwise (the paper's simulator experiment, Table II, keeps the paper's head).
        point_loss_weight: With the ray readout, the weight of a second loss: the squared
            distance (in normalised image units, [-1, 1] across the image) from each attention
            point to where the camera sees its target's grasp point, the label projected
            through the dataset's calibrated camera. Left to itself the point settles on the
            most telling part of an object, e.g. the spray bottle's blue head, whose offset from
            the grasp turns with the bottle's yaw, which a head cannot read from a few samples;
            on the grasp point the ray gives the grasp itself. The Query still chooses which
            object; only where on it the point sits is taught. Measured with a 64 x 64 heatmap
            (yumi ``multiple``, 20 demonstrations, 100 untrained scenes, bottle grasp error and
            grasps more than 8.5 mm off along the closing axis): 1 -> 0.80 cm, 16 of 100;
            10 -> 0.50 cm, 5 of 100. 0: the paper's free attention.
        rotation: How the head gives a grasp's rotation (:mod:`perception.models.rotations`).
            ``"6d"``: Zhou et al.'s 6-D representation. ``"axis-line"``: the approach axis and
            the closing axis's line tensor, the same for a grasp and its half-turn twin, so the
            sponge, whose labels switch twin where its closing axis is radial, has no seam to
            jump (a 6-D head averages the twins there into a frame that can point anywhere:
            yumi ``multiple`` picks approached sponges from below).
        mirror: Whether training also shows a random half of each batch mirrored across the
            world's xz-plane, labels mirrored with it (:mod:`perception.mirror`): valid where
            the camera sits on that plane (checked) and the task's targets are not ordered by
            their y. None: when the dataset's collector says its task allows it (the yumi
            collector checks camera, objects, workspace and target order: all four paper tasks
            do). Twenty demonstrations then show forty scenes: offline, yumi ``multiple``, 100
            untrained scenes, seed 0, spray bottle grasp error 0.39 -> 0.29 cm mean, mug grasps
            more than 8.5 mm off along the closing axis 25 -> 10 of 100.
        head_width: Width of the head MLP's two hidden layers (and of the type head's one).
        rotation_loss_weight: Weight of the chordal rotation loss against the position loss
            (squared distance in scaled units); 0.1 weighs 1 cm (at a 0.2 m label scale) like
            about 6 degrees of rotation.
        type_head: Whether a small MLP reads each head's ``a_feat`` and states the object type
            it attends to (over the dataset's ``object_types``). It trains after the pose, on
            the frozen network, and leaves the pose weights as they would be without it. None:
            for grasp-pose labels where the dataset names its object types, unless the
            condition is an object type (it names the type).
        type_steps: Optimiser steps of that type phase (batch size, rate and augmentation as
            the pose training's).
        seed: Seeds the initial weights.

    """

    channels: tuple[int, int] = (16, 32)
    key_dim: int = 16
    value_dim: int = 16
    input_norm: str = "auto"
    stride: int | None = None
    similarity: str = "cosine"
    temperature: float = 0.1
    warmup_temperature: float = 0.3
    warmup_steps: int = 300
    starts: int = 3
    start_steps: int = 300
    start_holdout: float = 0.2
    query_mode: str = "auto"
    head_features: bool | None = None
    readout: str = "auto"
    point_loss_weight: float = 10.0
    rotation: str = "axis-line"
    mirror: bool | None = None
    head_width: int = 64
    rotation_loss_weight: float = 0.1
    type_head: bool | None = None
    type_steps: int = 300
    seed: int = 0

    def __post_init__(self) -> None:
        channels = tuple(self.channels) if isinstance(self.channels, list | tuple) else ()
        if len(channels) != 2 or not all(isinstance(c, int) and c >= 1 for c in channels):
            raise InvalidInputError("channels", self.channels, "two integers >= 1")
        object.__setattr__(self, "channels", channels)  # a JSON list reads back as the tuple
        for name in ("key_dim", "value_dim", "head_width", "warmup_steps", "starts",
                     "start_steps", "type_steps"):
            value = getattr(self, name)
            least = 0 if name == "warmup_steps" else 1
            if not isinstance(value, int) or isinstance(value, bool) or value < least:
                raise InvalidInputError(name, value, f"an integer >= {least}")
        check_choices("stride", self.stride, (None, 1, 2, 4))
        check_choices("query_mode", self.query_mode, QUERY_MODES)
        check_choices("similarity", self.similarity, ("cosine", "dot"))
        check_choices("readout", self.readout, READOUTS)
        check_choices("input_norm", self.input_norm, INPUT_NORMS)
        check_choices("rotation", self.rotation, ROTATION_CODES)
        for name in ("temperature", "warmup_temperature"):
            if not (math.isfinite(getattr(self, name)) and getattr(self, name) > 0):
                raise InvalidInputError(name, getattr(self, name), "a finite value > 0")
        if not (math.isfinite(self.start_holdout) and 0 <= self.start_holdout < 1):
            raise InvalidInputError("start_holdout", self.start_holdout, "a fraction in [0, 1)")
        for name in ("rotation_loss_weight", "point_loss_weight"):
            if not (math.isfinite(getattr(self, name)) and getattr(self, name) >= 0):
                raise InvalidInputError(name, getattr(self, name), "a finite value >= 0")
        if self.mirror not in (None, True, False):
            raise InvalidInputError("mirror", self.mirror, "None, True or False")
        for name in ("head_features", "type_head"):
            if getattr(self, name) not in (None, True, False):
                raise InvalidInputError(name, getattr(self, name), "None, True or False")
        if not isinstance(self.seed, int) or self.seed < 0:
            raise InvalidInputError("seed", self.seed, "an integer >= 0")
