"""The KQV attention model's hyper-parameters.

:class:`KqvConfig` is what a ``kqv`` checkpoint's ``config.json`` keeps as ``hyperparameters``;
import it from :mod:`perception.models.kqv` or from here.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any, ClassVar

from perception.interface import InvalidInputError
from perception.learning.learnable import check_choices, check_integer, check_number
from perception.learning.rotations import ROTATION_CODES

QUERY_MODES = ("auto", "base", "conditioned", "conditioned+base", "paper")
READOUTS = ("auto-range", "auto", "mlp", "ray", "range")
INPUT_NORMS = ("auto", "fixed", "per-image")
VALUE_INPUTS = ("image", "depth")
SENTENCE_READINGS = ("auto", "tokens", "nearest", "prototypes", "embedding")
INFERENCE_FIELDS = frozenset({"focus_window_px", "focus_box_px"})
"""KqvConfig fields that only change how a trained network is read (``KqvModel.read_with``):
a checkpoint is scored under other values without training again."""


MOST: Mapping[str, int | float] = MappingProxyType({
    # The largest value of each of KqvConfig's numbers, each with why a larger one is a mistake
    # (a typo, a unit slip) rather than a setting; a config file asking more is refused.
    "channels": 1024,  # per conv layer on 128 px images: 64 x the default 16
    "key_dim": 4096,  # a heatmap key wider than any published attention model's
    "value_dim": 4096,  # a_feat wider than any published attention model's value
    "head_width": 4096,  # 64 x the default head; as wide as the widest MLP heads (VGG's fc)
    "warmup_steps": 1_000_000,  # a thousand default trainings (1000 steps) of warm-up alone
    "starts": 100,  # each trains start_steps of its own: 33 x the default 3
    "start_steps": 1_000_000,  # a thousand default trainings per start
    "start_batch_size": 4096,  # 4096 images of 128 x 128 x 3 float32 are 800 MB per step
    "type_steps": 1_000_000,  # a thousand default trainings for a head of a few hundred weights
    "focus_window_px": 4096,  # wider than any image gva renders (128 px; the D435 848 px)
    "focus_box_px": 4096,  # the same: a box wider than any image holds the whole heatmap
    "temperature": 1000.0,  # 10,000 x the default 0.1: every heatmap is flat
    "warmup_temperature": 1000.0,  # the same, at the warm-up's first step
    "sentence_temperature": 100.0,  # cosines lie in [-1, 1]: past 100 every weight is equal
    "point_loss_weight": 1000.0,  # 100 x the default: the pose loss it helps is drowned
    "rotation_loss_weight": 1000.0,  # 10,000 x the default: positions would not be learned
    "hue_jitter": 0.5,  # a share of a turn either way: 0.5 already reaches every hue
    "context_layers": 4,  # dilations 2, 4, 8, 16: past that a 3 x 3 kernel's taps leave the image
})


@dataclass(frozen=True)
class KqvConfig:
    """Hyper-parameters of the KQV attention model.

    Where a default departs from the paper, ``docs/decisions/kqv.md`` says why and what it was
    measured to do; ``"auto"`` and None pick a setting from the dataset (position labels: the
    paper's simulator experiment; grasp-pose labels with a recorded camera: the robot's).

    Args:
        channels: Output channels of the first two conv layers of FCN1 and of FCN2.
        key_dim: Ck, the Key's learned channels; Keys and Queries have Ck + 2 entries (the two
            coordinate channels ride along, so a Query can prefer a place as well as a look).
        value_dim: Cv, the Feature Value's channels (the length of ``a_feat``).
        input_norm: ``"fixed"``: ``(image - 0.5) / 0.25``; ``"per-image"``: each image's colour
            channels standardised by their own mean and spread (a darker room reads as the
            bright one); ``"auto"``: per-image for grasp-pose labels, fixed for positions.
        stride: Downsampling from image to heatmap, 1, 2 or 4 (128 x 128 images, 4: 32 x 32
            heatmaps). None: 2 with the ray readout, 4 otherwise.
        similarity: ``"dot"``: the paper's K · Q / sqrt(hw); ``"cosine"``: K and Q of unit
            length, logits in [-1, 1] before the temperature.
        temperature: Divides the logits before the 2-D softmax; inference always uses it.
        focus_window_px: At inference, each head reads ``a_coord`` and ``a_feat`` inside a
            square of this half-width [image px] around the densest part of its heatmap (the
            cell whose ``focus_box_px`` square holds the most attention), the heatmap
            renormalised there: attention split between a target and a look-alike reads the
            one holding more of it, not a point between them (docs/decisions/distractor.md).
            Training reads the whole heatmap. None: for grasp-pose labels (the robot's scene)
            the focus derived for the dataset's camera (its record's ``focus_window_px``: the
            YuMi head camera's 24 px; none for the Panda's stand camera), 0 for positions; 0:
            the whole heatmap, as the paper.
        focus_box_px: Side of the square [image px] whose attention mass finds that part:
            about one object's size in the image. None: the camera record's (18 px where it
            states none).
        focus_training: Whether training reads each heatmap through the same focus, once the
            temperature's warm-up is over, so the heads learn from the point inference reads
            (a spray bottle's heatmap spreads along its body; focused, it reads the shoulder,
            which a head trained on the whole map places 1-4 cm off). False (default): training
            reads the whole heatmap, as before.
        warmup_temperature: The temperature at the first training step; it falls linearly to
            ``temperature`` over ``warmup_steps`` steps, so every Query finds its objects before
            its heatmap can saturate.
        warmup_steps: Length of that warm-up, in optimiser steps (0: none).
        starts: Initialisations tried on a model's first fit; each trains ``start_steps`` steps
            and the best (see ``start_holdout``) goes on for the rest. 1: one start.
        start_holdout: Fraction of the training scenes the starts are compared on (held out of
            their ``start_steps``, trained on afterwards). 0: by training loss.
        start_steps: Steps each start trains before the choice (they count towards the total).
        start_batch_size: Samples per step of the starts; None: the training's batch size. A
            stalled start shows on fewer samples too, and the starts are most of a training's
            steps.
        query_mode: ``"base"`` (learned vectors), ``"conditioned"`` (MLP of the one-hot
            condition), ``"conditioned+base"`` (their sum, the condition's MLP started at zero)
            or ``"auto"``: base without a condition, conditioned+base for an object type
            (one-hot, a sentence or a picture), conditioned for a side (one-hot or a sentence);
            ``"paper"``: base without a condition, conditioned with one (the paper's Sec. IV-B).
        head_features: Whether the head MLP reads ``a_feat`` besides ``a_coord``. None: for
            grasp labels and the ray readout; coordinates only for positions read by the MLP.
        head_coords: Whether the ray readout's head reads ``a_coord`` too (the MLP readout
            always does): where in the image the point lies, from which the head may tell a
            sponge seen end-on from one seen side-on (docs/decisions/grasp-judge.md). False:
            the attended feature alone.
        readout: ``"mlp"``: the paper's MLP maps ``a_coord`` (and ``a_feat``) to the target.
            ``"ray"``: the target is read off the ray through ``a_coord`` of the frame's
            calibrated camera, at a height, offset and rotation the MLP gives from ``a_feat``.
            ``"range"``: as ``"ray"``, but the point on the ray lies at the range the frame's
            depth measures under the heatmap (the head's height only where it measured none),
            so the head learns no range the camera measures; it reads depth (a dataset without
            depth images is refused). ``"auto-range"``, the default: for grasp-pose labels where
            the dataset records its camera, range where its images come through a depth sensor
            (the D435; ray if it kept no depth images) and ray through the ideal camera, whose
            runs read as they always did; the MLP otherwise (issue 75: under the D435 a ray
            readout learned the bottle's range, and at one seed in eleven learned it wrong).
            ``"auto"``: the default before it, ray for grasp-pose labels where the dataset
            records its camera, the MLP otherwise; it keeps its meaning so checkpoints and
            model files that name it read as they trained.
        point_loss_weight: Weight of a second loss, where the dataset records its camera: the
            squared distance (normalised image units) from each attention point to where the
            camera sees its target (the label projected). The Query still chooses the object;
            the loss teaches where on it the point sits, and lets it find the objects at all
            (paper-sim ``selected-position``). 0: the paper's free attention.
        rotation: How the head gives a grasp's rotation (:mod:`perception.learning.rotations`):
            ``"6d"`` (Zhou et al.) or ``"axis-line"`` (the approach axis and the closing axis's
            line tensor, the same for a grasp and its half-turn twin).
        mirror: Whether training also shows a random half of each batch mirrored across the
            world's xz-plane, labels with it (:mod:`perception.learning.mirror`). None: where the
            dataset's collector says its task allows it.
        head_width: Width of the head MLP's two hidden layers (and of the type head's one).
        rotation_loss_weight: Weight of the chordal rotation loss against the position loss;
            0.1 weighs 1 cm (at a 0.2 m label scale) like about 6 degrees.
        type_head: Whether a small MLP reads each head's ``a_feat`` and states the object type
            it attends to; it trains after the pose, on the frozen network. None: for grasp-pose
            labels where the dataset names its types, unless the condition is an object type.
        type_steps: Optimiser steps of that type phase; a training asked for fewer steps
            (``TrainConfig.steps``) trains the type head that many.
        sentence_reading: How a sentence condition becomes a Query. Each named target has a
            prototype, the mean embedding of the training sentences that named it, and a
            sentence's weights are the softmax of its cosines to them at
            ``sentence_temperature``. ``"nearest"``: the Query of the target it reads most
            likely (a sentence names one target, and a Query between two attends to neither);
            ``"tokens"``: the Query of the target a
            :class:`~perception.language.sentence_reading.TokenReader`, trained at the first fit
            on the training sentences, reads from the encoder's token embeddings (the pooled vector
            averages a side's one word away); ``"auto"``: ``"nearest"`` where every target is
            an object type (the noun carries the pooled vector), else ``"tokens"``
            (docs/decisions/open-conditions.md measures both per kind); ``"prototypes"``: the
            weighted mean of the targets' Queries; ``"embedding"``: the Query MLP reads the
            384-d embedding itself (checkpoints from before prototypes).
        sentence_temperature: Divides those cosines before the softmax (the weights
            ``KqvModel.read_sentences`` reports; ``"nearest"`` reads only their largest).
        seed: Seeds the initial weights.
        hue_jitter: Training images' hues turned by up to this share of a turn either way
            (:attr:`perception.learning.train.TrainConfig.hue_jitter`): for worlds of many
            colourways, where hue names no type. 0 (default): no turn.
        context_layers: 3 x 3 convolutions of dilation 2, 4, ... added to FCN1 and FCN2 before
            their last layer (a context module, Yu and Koltun 2016): each Key then sees past an
            object's edge (receptive field 13 px of a 128 px image at 0, 37 px at 2), so a
            type can be told by its shape where colours name none. 0 (default): the three
            layers of the paper's FCNs.
        depth_input: Whether FCN1 and FCN2 also read each pixel's rise above the table, from
            the depth image (:mod:`perception.models.rise`): the objects' shapes whatever their
            colours and prints. The model then reads a frame's depth (datasets without depth
            are refused). False (default): the colour image alone, as the paper.
        value_input: What FCN2, the Value map the pose and type heads read, sees: ``"image"``
            (default) what FCN1 sees; ``"depth"`` the rise above the table alone (needs
            ``depth_input``). The Key still finds the target by colour and shape; what the
            heads read of it is its geometry, which a print or a colourway never seen does not
            change (grasps from depth alone: GG-CNN, Morrison et al., RSS 2018).
        repaint: The share of training images whose objects the Value map sees painted in a
            random pattern (:mod:`perception.models.repaint`; the Key sees them as they are),
            so the heads read a pose from an object's outline and not from its print. Needs
            training data with depth. 0 (default): none.

    """

    channels: tuple[int, int] = (16, 16)
    key_dim: int = 16
    value_dim: int = 16
    input_norm: str = "auto"
    stride: int | None = None
    similarity: str = "cosine"
    temperature: float = 0.1
    focus_window_px: int | None = None
    focus_box_px: int | None = None
    focus_training: bool = False
    warmup_temperature: float = 0.3
    warmup_steps: int = 300
    starts: int = 3
    start_steps: int = 300
    start_holdout: float = 0.2
    start_batch_size: int | None = 8
    query_mode: str = "auto"
    head_features: bool | None = None
    head_coords: bool = False
    readout: str = "auto-range"
    point_loss_weight: float = 10.0
    rotation: str = "axis-line"
    mirror: bool | None = None
    head_width: int = 64
    rotation_loss_weight: float = 0.1
    type_head: bool | None = None
    type_steps: int = 300
    sentence_reading: str = "auto"
    sentence_temperature: float = 0.02
    hue_jitter: float = 0.0
    context_layers: int = 0
    depth_input: bool = False
    value_input: str = "image"
    repaint: float = 0.0
    seed: int = 0

    SINCE: ClassVar[Mapping[str, Any]] = MappingProxyType({"focus_training": False,
                                                       "hue_jitter": 0.0, "context_layers": 0,
                                                       "depth_input": False,
                                                       "value_input": "image",
                                                       "repaint": 0.0})
    """Fields added later, at the value that trains as before them: left out of a run's
    identity there, so folders made before them resume (``experiments.tables.model_config``)."""

    def __post_init__(self) -> None:
        channels = tuple(self.channels) if isinstance(self.channels, list | tuple) else ()
        if len(channels) != 2 or not all(isinstance(c, int) and not isinstance(c, bool) and
                                         1 <= c <= MOST["channels"] for c in channels):
            raise InvalidInputError("channels", self.channels,
                                    f"two integers >= 1 and <= {MOST['channels']}")
        object.__setattr__(self, "channels", channels)  # a JSON list reads back as the tuple
        for name in ("key_dim", "value_dim", "head_width", "warmup_steps", "starts",
                     "start_steps", "type_steps"):
            check_integer(name, getattr(self, name), 0 if name == "warmup_steps" else 1,
                          int(MOST[name]))
        for name, least in (("focus_window_px", 0), ("focus_box_px", 1),
                            ("start_batch_size", 1)):
            check_integer(name, getattr(self, name), least, int(MOST[name]), optional=True)
        check_choices("stride", self.stride, (None, 1, 2, 4))
        check_choices("query_mode", self.query_mode, QUERY_MODES)
        check_choices("similarity", self.similarity, ("cosine", "dot"))
        check_choices("readout", self.readout, READOUTS)
        check_choices("input_norm", self.input_norm, INPUT_NORMS)
        check_choices("rotation", self.rotation, ROTATION_CODES)
        check_choices("sentence_reading", self.sentence_reading, SENTENCE_READINGS)
        for name in ("temperature", "warmup_temperature", "sentence_temperature"):
            check_number(name, getattr(self, name), 0, MOST[name], open_below=True)
        if not (math.isfinite(self.start_holdout) and 0 <= self.start_holdout < 1):
            raise InvalidInputError("start_holdout", self.start_holdout, "a fraction in [0, 1)")
        check_number("hue_jitter", self.hue_jitter, 0.0, MOST["hue_jitter"])
        check_integer("context_layers", self.context_layers, 0, int(MOST["context_layers"]))
        for name in ("rotation_loss_weight", "point_loss_weight"):
            check_number(name, getattr(self, name), 0, MOST[name])
        if self.mirror not in (None, True, False):
            raise InvalidInputError("mirror", self.mirror, "None, True or False")
        for name in ("head_features", "type_head"):
            if getattr(self, name) not in (None, True, False):
                raise InvalidInputError(name, getattr(self, name), "None, True or False")
        if not isinstance(self.focus_training, bool):
            raise InvalidInputError("focus_training", self.focus_training, "True or False")
        if not isinstance(self.depth_input, bool):
            raise InvalidInputError("depth_input", self.depth_input, "True or False")
        check_number("repaint", self.repaint, 0.0, 1.0)
        check_choices("value_input", self.value_input, VALUE_INPUTS)
        if self.value_input == "depth" and not self.depth_input:
            raise InvalidInputError("value_input", self.value_input,
                                    "'image', or 'depth' with depth_input = true")
        if self.head_coords not in (True, False):
            raise InvalidInputError("head_coords", self.head_coords, "True or False")
        if not isinstance(self.seed, int) or self.seed < 0:
            raise InvalidInputError("seed", self.seed, "an integer >= 0")


PAPER: Mapping[str, Any] = MappingProxyType({
    # "The model computes pixel-wise dot product of K and a Query vector Q, and applies 2D
    # softmax with temperature": M = Softmax2D(K (.) Q / sqrt(HW)) (Sec. III-B). The
    # temperature's value is not given: gva's 0.1, with no warm-up.
    "similarity": "dot", "warmup_steps": 0,
    # One training from one initialisation; nothing is said of starts compared.
    "starts": 1,
    # "the Base Queries and Conditioned Queries were used for the baseline tasks and top-down
    # tasks, respectively" (Sec. IV-B).
    "query_mode": "paper",
    # "MLPs were used to convert attention coordinate values to object coordinates in simulator
    # environment. Similarly, attention coordinate and feature values were concatenated and
    # converted to robot picking poses with MLPs" (Sec. IV-B): the MLP readout; head_features
    # None reads coordinates alone for positions, coordinates and features for poses.
    "readout": "mlp", "head_features": None,
    # "acquires attention through end-to-end learning, without any explicit supervisions of
    # where or what to attend to" (Sec. III-A): no point loss.
    "point_loss_weight": 0.0,
    # Three-layered FCNs whose first two layers halve the image twice: 32 x 32 heatmaps of a
    # 128 x 128 image (docs/decisions/kqv.md's paper column), read whole.
    "stride": 4, "focus_window_px": 0,
    # Nothing in the paper scales each image, mirrors samples or names the attended type.
    "input_norm": "fixed", "mirror": False, "type_head": False,
})
"""``kqv-paper``: the :class:`KqvConfig` fields the paper's model sets, each with its sentence.

Where the paper is silent (widths, the temperature's value, the rotation code, optimiser, steps,
augmentation of colours) the preset keeps what every model here uses.
"""
