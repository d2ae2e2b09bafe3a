"""The KQV attention network (Hiruma et al.): Keys, Values, Queries, heatmaps and heads.

Selection: the Key ``K = FCN1(image)`` (CoordConv) meets one Query per head in a heatmap
``M = Softmax2D(similarity(K, Q) / temperature)``. Extraction: ``a_feat = Σ M FCN2(image)`` and
``a_coord = Σ M [x, y]`` (at inference over the densest part of ``M``). A head MLP maps each
head's ``a_coord`` and ``a_feat`` to its target, or reads it off the camera ray through
``a_coord``; a type head names what each head sees.
Where and why it departs from the paper: ``docs/decisions/kqv.md``.
"""

from __future__ import annotations

import math
from typing import NamedTuple, cast

import torch
from torch import Tensor, nn

from perception.camera import Calibrations
from perception.interface import PICTURE_PX, ConditionKind, InvalidInputError, LabelKind
from perception.language.sentence_reading import TokenReader
from perception.learning.learnable import ModelSpec
from perception.learning.rotations import decode_rotation, rotation_size
from perception.learning.torch_pieces import (
    MLP,
    CoordConv,
    CoordConvStack,
    LabelScaler,
    coordinate_grid,
    focus,
    normalise_images,
    softmax2d,
    spatial_expectation,
    unit,
)
from perception.models.kqv_config import KqvConfig
from perception.models.readout import CameraRays, attended_range
from perception.models.rise import RISE_SCALE_M, rise_above_table
from perception.models.torch_model import NetOutput
from robots.yumi import HEAD_CAMERA


class Attention(NamedTuple):
    """What the heads attend to (tensors, batch first)."""

    heatmaps: Tensor  # (B, q, h, w) M, each map sums to 1
    coords: Tensor  # (B, q, 2) a_coord, (x, y) in [-1, 1]
    features: Tensor  # (B, q, Cv) a_feat


FOCUS_WINDOW_PX = HEAD_CAMERA.focus_window_px
"""KqvConfig.focus_window_px's value for grasp-pose labels whose dataset's camera record states
no focus: such datasets are the YuMi head camera's, from before records stated it."""
FOCUS_BOX_PX = HEAD_CAMERA.focus_box_px
"""KqvConfig.focus_box_px's value where neither the config nor the camera's record states one."""


class FocusPx(NamedTuple):
    """A heatmap focus's sizes in image pixels (``KqvConfig.focus_window_px``, ``focus_box_px``)."""

    window_px: int  # 0: the whole heatmap
    box_px: int


def focus_px(spec: ModelSpec, config: KqvConfig) -> FocusPx:
    """The heatmap focus a model of ``spec`` reads with under ``config``.

    None in the config takes the camera's record: its focus for grasp-pose labels (the robot's
    scene, each camera its own, :class:`robots.description.CameraMount`), none for positions
    (the paper's scene, read whole).
    """
    window_px, box_px = config.focus_window_px, config.focus_box_px
    if window_px is None:
        grasp = spec.label_kind is LabelKind.GRASP_POSE
        recorded = FOCUS_WINDOW_PX if spec.focus_window_px is None else spec.focus_window_px
        window_px = recorded if grasp else 0
    if box_px is None:
        box_px = spec.focus_box_px or FOCUS_BOX_PX
    return FocusPx(window_px, box_px)

PICTURE_FEATURES = 32
"""What the picture encoder makes of an image condition: 32 numbers, as a one-hot has a few."""


def picture_encoder() -> nn.Sequential:
    """A small CNN: a (B, 3, 32, 32) picture -> (B, :data:`PICTURE_FEATURES`) features.

    Three stride-2 convolutions (32 -> 4 px) and a mean over the cells: colour and shape of
    the pictured object, wherever it lies in the picture. 14 k weights: it learns from the few
    hundred pictures of a training set without memorising them.
    """
    return nn.Sequential(
        nn.Conv2d(3, 16, 3, 2, 1), nn.ReLU(),
        nn.Conv2d(16, 32, 3, 2, 1), nn.ReLU(),
        nn.Conv2d(32, PICTURE_FEATURES, 3, 2, 1), nn.ReLU(),
        nn.AdaptiveAvgPool2d(1), nn.Flatten())


def sentence_reading(spec: ModelSpec, config: KqvConfig) -> str:
    """The :attr:`KqvConfig.sentence_reading` a model of ``spec`` uses, ``"auto"`` resolved.

    A sentence naming an object type is read by its pooled embedding's nearest prototype (the
    noun carries it); one naming a side by its token embeddings, where a side's one word is not
    averaged away (docs/decisions/open-conditions.md).
    """
    if config.sentence_reading != "auto":
        return config.sentence_reading
    return "nearest" if names_object_types(spec) else "tokens"


def names_object_types(spec: ModelSpec) -> bool:
    """Whether every target ``spec``'s condition may name is an object type (else: sides)."""
    choices = spec.condition_choices
    return bool(choices) and set(choices) <= set(spec.object_types)


class KqvNet(nn.Module):
    """The network: FCN1 (Key), FCN2 (Feature Value), the Queries, the head MLP, the type head."""

    prototypes: Tensor | None  # (k, C) a sentence task's target prototypes, or None

    def __init__(self, spec: ModelSpec, config: KqvConfig) -> None:
        super().__init__()
        c, key, value = config, config.key_dim, config.value_dim
        (wide1, wide2), hidden = config.channels, config.channels[1]
        self.readout = c.readout
        if self.readout in ("auto", "auto-range"):
            through_camera = spec.label_kind is LabelKind.GRASP_POSE and spec.camera is not None
            measured = self.readout == "auto-range" and spec.sensor is not None  # a depth sensor
            self.readout = ("range" if measured else "ray") if through_camera else "mlp"
        self.stride = c.stride or (4 if self.readout == "mlp" else 2)
        first, second = {1: (1, 1), 2: (2, 1), 4: (2, 2)}[self.stride]
        norm = c.input_norm
        if norm == "auto":
            norm = "per-image" if spec.label_kind is LabelKind.GRASP_POSE else "fixed"
        self.per_image = norm == "per-image"
        self.temperature = c.temperature
        window_px, box_px = focus_px(spec, c)
        self.focus_cells = (round(window_px / self.stride), round(box_px / self.stride))
        self.focus_now = False  # training reads through the focus (KqvModel sets it per step)
        self.similarity = c.similarity
        # KqvConfig.context_layers: dilated 3 x 3 layers before each FCN's last, so a Key sees
        # an object's outline and not only its colour.
        dilations = [2 ** (i + 1) for i in range(c.context_layers)]
        self.depth_input = c.depth_input  # a fourth input channel: the rise above the table
        colours = 4 if self.depth_input else 3
        self.values_from_depth = c.value_input == "depth"  # FCN2 reads the rise alone
        self.key_net = CoordConvStack(  # FCN1 with CoordConv: (B, 3, H, W) -> (B, Ck + 2, h, w)
            CoordConv(colours, wide1, 5, first),
            CoordConv(wide1 + 2, wide2, 3, second),
            *(CoordConv(wide2 + 2, wide2, 3, 1, dilation=d) for d in dilations),
            CoordConv(wide2 + 2, key, 3, 1, activation=False),
        )
        self.value_net = nn.Sequential(  # FCN2, own weights: (B, 3, H, W) -> (B, Cv, h, w)
            nn.Conv2d(1 if self.values_from_depth else colours, wide1, 5, first, 2), nn.ReLU(),
            nn.Conv2d(wide1, wide2, 3, second, 1), nn.ReLU(),
            *(layer for d in dilations
              for layer in (nn.Conv2d(wide2, wide2, 3, 1, d, d), nn.ReLU())),
            nn.Conv2d(wide2, value, 3, 1, 1),
        )
        mode = c.query_mode
        if mode == "paper":  # Base Queries without a condition, Conditioned ones with one
            mode = "base" if spec.condition_kind is ConditionKind.NONE else "conditioned"
        if mode == "auto":
            # A picture names a type: it refines the shared Base Query too, as a type's one-hot
            # does. A sentence takes its one-hot twin's form: a type's, or a side's (alone).
            mode = {ConditionKind.NONE: "base", ConditionKind.OBJECT_TYPE: "conditioned+base",
                    ConditionKind.SIDE: "conditioned", ConditionKind.IMAGE: "conditioned+base",
                    ConditionKind.TEXT: "conditioned+base" if names_object_types(spec)
                    else "conditioned"}[spec.condition_kind]
        if "conditioned" in mode and not spec.condition_size:
            raise InvalidInputError("query_mode", c.query_mode, "'base' or 'auto' for a task "
                                    "without a condition")
        self.targets, query_dim = spec.targets, key + 2
        self.base_queries = nn.Parameter(torch.randn(spec.targets, query_dim)) \
            if "base" in mode else None  # (q, Ck + 2)
        pictured = spec.condition_kind is ConditionKind.IMAGE
        condition_in = PICTURE_FEATURES if pictured else spec.condition_size
        # A sentence is read by its likeness to each named target's training sentences
        # (KqvConfig.sentence_reading); the prototypes come from the first fit's dataset.
        self.sentence_temperature = c.sentence_temperature
        reading = sentence_reading(spec, c)
        self.nearest_sentence = reading in ("nearest", "tokens")  # "tokens": the model reads
        if spec.condition_kind is ConditionKind.TEXT and reading != "embedding":  # the target
            self.register_buffer("prototypes", torch.zeros(len(spec.condition_choices),
                                                           spec.condition_size))  # (k, C)
            condition_in = len(spec.condition_choices)
        else:
            self.prototypes = None
        self.query_mlp = MLP((condition_in, hidden, spec.targets * query_dim)) \
            if "conditioned" in mode else None
        if self.query_mlp is not None and self.base_queries is not None:
            # The condition starts as no change to the Base Query: every condition first
            # attends where the shared Query does (to objects), then learns to pick one.
            last = cast(nn.Linear, self.query_mlp[-1])
            nn.init.zeros_(last.weight)
            nn.init.zeros_(last.bias)
        self.rays = None if self.readout == "mlp" else CameraRays(spec)  # "ray" or "range"
        # Where the camera sees each target: the point loss's aim, on either readout.
        self.seen = self.rays
        if self.seen is None and spec.camera is not None and c.point_loss_weight > 0:
            self.seen = CameraRays(spec)
        reads_features = c.head_features
        if reads_features is None:
            reads_features = spec.label_kind is LabelKind.GRASP_POSE or self.rays is not None
        if self.rays is not None and not reads_features:
            raise InvalidInputError("head_features", c.head_features,
                                    "True or None with readout 'ray' (its head reads a_feat)")
        self.head_features = reads_features
        self.scaler: LabelScaler | None = None  # the ray readout's metres <-> network units
        # One MLP shared by every head: the image-to-world mapping is one camera's geometry, so
        # each head learns it from q times the samples; a one-hot head index tells them apart.
        # The ray readout's head reads no coordinates unless asked (head_coords): the camera
        # places the point.
        self.head_coords = self.rays is None or c.head_coords
        head_in = (2 if self.head_coords else 0) + (value if reads_features else 0) + \
            (spec.targets if spec.targets > 1 else 0)
        self.rotation = c.rotation if spec.label_kind is LabelKind.GRASP_POSE else None
        self.place_size = 3 if self.rays is None else 4  # position | height and offset
        head_out = self.place_size + (rotation_size(self.rotation) if self.rotation else 0)
        self.head = MLP((head_in, c.head_width, c.head_width, head_out))
        # Built after every other module, so theirs draw the same random weights either way.
        # It reads a_feat alone, no head index: it states what the head sees, not its slot.
        types = spec.object_types
        wanted = c.type_head
        if wanted is None:  # an object-type condition names the type itself
            wanted = spec.label_kind is LabelKind.GRASP_POSE and bool(types) and \
                spec.condition_kind is not ConditionKind.OBJECT_TYPE
        if wanted and not types:
            raise InvalidInputError("type_head", c.type_head, "None or False for a dataset "
                                    "that names no object types")
        # a_feat differs little between objects next to its own size (a heatmap mixes object
        # and table): the head standardises it first, so its differences are what it reads.
        self.type_head = nn.Sequential(nn.LayerNorm(value), MLP((value, c.head_width,
                                                                 len(types)))) if wanted else None
        # An image condition's picture is read by a small CNN trained with the rest (last, too).
        self.picture_net = picture_encoder() if pictured else None
        # What target a sentence names, read from its words (KqvModel.condition_rows); trained
        # at the first fit on the training sentences, apart from the rest, and saved with it.
        self.reader = TokenReader(len(spec.condition_choices)) \
            if spec.condition_kind is ConditionKind.TEXT and reading == "tokens" else None

    def queries(self, conditions: Tensor) -> Tensor:
        """The Query vectors for condition vectors (B, C): (B, q, Ck + 2)."""
        batch = conditions.shape[0]
        parts = []
        if self.base_queries is not None:
            parts.append(self.base_queries.expand(batch, -1, -1))  # (B, q, Ck + 2)
        if self.query_mlp is not None:
            parts.append(self.conditioned_queries(self.query_mlp, conditions)
                         .view(batch, self.targets, -1))
        return torch.stack(parts).sum(dim=0)  # (B, q, Ck + 2)

    def conditioned_queries(self, mlp: nn.Module, conditions: Tensor) -> Tensor:
        """The Conditioned-Query MLP's answer for condition vectors (B, C): (B, q (Ck + 2))."""
        if self.picture_net is not None:  # rows of pixels -> (B, PICTURE_FEATURES)
            pictures = conditions.view(-1, PICTURE_PX, PICTURE_PX, 3).permute(0, 3, 1, 2)
            return mlp(self.picture_net((pictures - 0.5) / 0.25))
        if self.prototypes is not None:
            # The Query of the target a sentence reads most likely, or (``"prototypes"``) the
            # mean of the targets' Queries under its weights; each target's Query is the MLP of
            # its one-hot, so a sentence read right attends as the one-hot condition does.
            own = mlp(torch.eye(len(self.prototypes), device=conditions.device))  # (k, ...)
            weights = self.sentence_weights(conditions)  # (B, k)
            if self.nearest_sentence:
                return own[weights.argmax(dim=-1)]
            return weights @ own
        return mlp(conditions)

    def sentence_weights(self, embeddings: Tensor) -> Tensor:
        """How sentence embeddings (B, C) read as the named targets: (B, k), rows summing to 1.

        The softmax, at ``sentence_temperature``, of each sentence's cosine to every target's
        prototype. Raises where the network reads sentences otherwise.
        """
        if self.prototypes is None:
            raise InvalidInputError("sentence_reading", "'embedding' or no sentence task",
                                    "a kqv model of a sentence task that reads by prototypes")
        cosines = unit(embeddings, dim=-1) @ unit(self.prototypes, dim=-1).T  # (B, k)
        return torch.softmax(cosines / self.sentence_temperature, dim=-1)

    def attend(self, images: Tensor, queries: Tensor, depths_m: Tensor | None = None,
               value_images: Tensor | None = None) -> Attention:
        """Selection and extraction: images (B, 3, H, W) in [0, 1], queries (B, q', Ck + 2).

        At inference each heatmap is first focused on its densest part (``focus_window_px``);
        the returned heatmaps are the ones read. ``depths_m`` (B, H, W): the images' depth,
        which a network built with ``depth_input`` reads (and needs). ``value_images``: other
        images for the Value map alone (training's repainted copies, ``KqvConfig.repaint``).
        """
        x = normalise_images(images, self.per_image)  # (B, 3, H, W)
        seen = None if value_images is None else normalise_images(value_images, self.per_image)
        if self.depth_input:
            if depths_m is None:
                raise InvalidInputError("depth", None, "each image's depth, for a kqv model "
                                        "with depth_input = true")
            rise = rise_above_table(depths_m.to(images))[:, None] / RISE_SCALE_M  # (B, 1, H, W)
            x = torch.cat([x, rise], dim=1)  # (B, 4, H, W)
            if seen is not None:
                seen = torch.cat([seen, rise], dim=1)
        seen = x if seen is None else seen  # the Value map's input: the Key's, or repainted
        keys = self.key_net(x)  # (B, Ck + 2, h, w)
        values = self.value_net(seen[:, 3:] if self.values_from_depth else seen)  # (B, Cv, h, w)
        height, width = keys.shape[-2:]
        if self.similarity == "cosine":
            # Each cell's dot product with the unit Query over the cell's Key length: the
            # cosine, without making (and differentiating) a unit copy of the Key map.
            lengths = keys.square().sum(1, keepdim=True).clamp_min(1e-24)  # (B, 1, h, w)
            queries = unit(queries, dim=-1)  # (B, q', Ck + 2)
            logits = torch.einsum("bchw,bqc->bqhw", keys, queries) * torch.rsqrt(
                lengths)  # (B, q', h, w) in [-1, 1]
        else:
            logits = torch.einsum("bchw,bqc->bqhw", keys, queries) / math.sqrt(height * width)
        heatmaps = softmax2d(logits, self.temperature)  # (B, q', h, w)
        if self.focus_cells[0] > 0 and (not self.training or self.focus_now):
            heatmaps = focus(heatmaps, self.focus_cells[1], self.focus_cells[0])
        grid = coordinate_grid(height, width, images.device)  # (2, h, w)
        return Attention(heatmaps, spatial_expectation(heatmaps, grid),  # (B, q', 2)
                         spatial_expectation(heatmaps, values))  # (B, q', Cv)

    def forward(self, images: Tensor, conditions: Tensor, queries: Tensor | None = None,
                depths_m: Tensor | None = None, value_images: Tensor | None = None,
                cameras: Calibrations = None) -> NetOutput:
        """Targets for images (B, 3, H, W) in [0, 1] under conditions (B, C) (or given Queries).

        ``depths_m`` (B, H, W) and ``value_images``: as :meth:`attend` reads them. ``cameras``:
        each image's calibration, which the ray readout reads through (None: the spec's).
        """
        attention = self.attend(images, self.queries(conditions) if queries is None else queries,
                                depths_m, value_images)
        batch, heads = attention.coords.shape[:2]
        parts = [attention.coords] if self.head_coords else []  # (B, q, 2)
        if self.head_features:
            parts.append(attention.features)  # (B, q, Cv)
        if self.targets > 1:
            parts.append(torch.eye(heads, device=images.device).expand(batch, -1, -1))
        out = self.head(torch.cat(parts, dim=-1))  # (B, q, 3 | 4 (+ 6 | 9 for a rotation))
        place, turn = out[..., :self.place_size], None
        if self.rays is None:
            positions = place  # (B, q, 3)
        else:
            if self.scaler is None:
                raise InvalidInputError("scaler", None, "a LabelScaler before the ray readout "
                                        "runs (KqvModel sets it on fit and load)")
            measured = None
            if self.readout == "range":  # the frame's depth measures how far the point lies
                if depths_m is None:
                    raise InvalidInputError("depths_m", None, "each image's depth, for a kqv "
                                            "model with readout = 'range'")
                measured = attended_range(attention.heatmaps, depths_m.to(images))
            positions, turn = self.rays.read(attention.coords, place, self.scaler, cameras,
                                             measured)
        rotations = lines = None
        if self.rotation is not None:  # (B, q, 3, 3), (B, q, 3, 4) | None
            rotations, lines = decode_rotation(out[..., self.place_size:], self.rotation, turn)
        types = None if self.type_head is None else self.type_head(attention.features)
        return NetOutput(positions, rotations, attention.coords, attention.heatmaps, lines,
                         types)  # types: (B, q, T) | None
