"""The paper's Key-Query-Value visual attention model (Hiruma et al.), the whole of it.

Selection: the Key ``K = FCN1(image)`` (three conv layers, the x/y coordinate channels appended
after each: CoordConv) meets one Query vector per head; the heatmap is
``M = Softmax2D(K · Q / sqrt(hw) / temperature)`` as in the paper (``similarity="dot"``) or, by
default, ``Softmax2D(cos(K, Q) / temperature)`` (see :class:`KqvConfig`). Extraction: the
Feature Value ``V_feat = FCN2(image)`` (own weights) and the Coordinate Value (the x/y channels)
are averaged under ``M``: ``a_feat = Σ M V_feat``, ``a_coord = Σ M [x, y]``. An MLP maps each head's
``a_coord`` (and ``a_feat`` where configured) to its target, as in the paper, or, for grasp poses
seen by a calibrated camera, reads the target off the ray through ``a_coord`` at a height the
MLP gives from ``a_feat`` (:class:`CameraRays`, ``KqvConfig.readout``). Queries are learnable
Base Queries, Conditioned Queries ``MLP(one-hot condition)``, or their sum; :meth:`KqvModel.attend`
runs the selection with Queries supplied from outside, so the top-down target can be replaced at
inference. Where the dataset names its object types, a small type head reads each ``a_feat`` too
and states the type of what the head attends to (``KqvConfig.type_head``); it trains after the
pose, on the frozen network, so a pick can take its grip from what the model sees.

The image is read at full size (128 x 128) but the first two layers of each FCN have stride 2
(:attr:`KqvConfig.stride`), so the heatmaps are 32 x 32: four times fewer cells to attend over
and sixteen times less work per layer, which keeps training on two CPU cores within minutes;
``a_coord`` is an expectation, so it still resolves positions between cells. A grasp read
through the camera needs finer points: there only the first layer has stride 2 (64 x 64).
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import NamedTuple, cast

import numpy as np
import torch
from torch import Tensor, nn

from perception.data import Dataset
from perception.evaluate import evaluate
from perception.interface import ConditionKind, InvalidInputError, LabelKind, Prediction
from perception.learnable import ModelSpec
from perception.mirror import MIRROR_FLAG, Mirror
from perception.models.base import (
    MLP,
    CoordConv,
    LabelScaler,
    coordinate_grid,
    images_to_tensor,
    normalise_images,
    normalised_to_pixels,
    softmax2d,
    spatial_expectation,
    unit,
)
from perception.models.kqv_config import KqvConfig
from perception.models.readout import CameraRays
from perception.models.rotations import decode_rotation, rotation_size
from perception.models.torch_model import NetOutput, Phase, TorchModel, present_mean
from perception.train import Batch, TrainConfig, TrainReport, train
from perception.validation import split_scenes


class Attention(NamedTuple):
    """What the heads attend to (tensors, batch first)."""

    heatmaps: Tensor  # (B, q, h, w) M, each map sums to 1
    coords: Tensor  # (B, q, 2) a_coord, (x, y) in [-1, 1]
    features: Tensor  # (B, q, Cv) a_feat


class KqvNet(nn.Module):
    """The network: FCN1 (Key), FCN2 (Feature Value), the Queries, the head MLP, the type head."""

    def __init__(self, spec: ModelSpec, config: KqvConfig) -> None:
        super().__init__()
        c, key, value = config, config.key_dim, config.value_dim
        (wide1, wide2), hidden = config.channels, config.channels[1]
        self.readout = c.readout
        if self.readout == "auto":
            self.readout = "ray" if spec.label_kind is LabelKind.GRASP_POSE and \
                spec.camera is not None else "mlp"
        self.stride = c.stride or (2 if self.readout == "ray" else 4)
        first, second = {1: (1, 1), 2: (2, 1), 4: (2, 2)}[self.stride]
        norm = c.input_norm
        if norm == "auto":
            norm = "per-image" if spec.label_kind is LabelKind.GRASP_POSE else "fixed"
        self.per_image = norm == "per-image"
        self.temperature = c.temperature
        self.similarity = c.similarity
        self.key_net = nn.Sequential(  # FCN1 with CoordConv: (B, 3, H, W) -> (B, Ck + 2, h, w)
            CoordConv(3, wide1, 5, first),
            CoordConv(wide1 + 2, wide2, 3, second),
            CoordConv(wide2 + 2, key, 3, 1, activation=False),
        )
        self.value_net = nn.Sequential(  # FCN2, own weights: (B, 3, H, W) -> (B, Cv, h, w)
            nn.Conv2d(3, wide1, 5, first, 2), nn.ReLU(),
            nn.Conv2d(wide1, wide2, 3, second, 1), nn.ReLU(),
            nn.Conv2d(wide2, value, 3, 1, 1),
        )
        mode = c.query_mode
        if mode == "auto":
            mode = {ConditionKind.NONE: "base", ConditionKind.OBJECT_TYPE: "conditioned+base",
                    ConditionKind.SIDE: "conditioned"}[spec.condition_kind]
        if "conditioned" in mode and not spec.condition_size:
            raise InvalidInputError("query_mode", c.query_mode, "'base' or 'auto' for a task "
                                    "without a condition")
        self.targets, query_dim = spec.targets, key + 2
        self.base_queries = nn.Parameter(torch.randn(spec.targets, query_dim)) \
            if "base" in mode else None  # (q, Ck + 2)
        self.query_mlp = MLP((spec.condition_size, hidden, spec.targets * query_dim)) \
            if "conditioned" in mode else None
        if self.query_mlp is not None and self.base_queries is not None:
            # The condition starts as no change to the Base Query: every condition first
            # attends where the shared Query does (to objects), then learns to pick one.
            last = cast(nn.Linear, self.query_mlp[-1])
            nn.init.zeros_(last.weight)
            nn.init.zeros_(last.bias)
        self.rays = CameraRays(spec) if self.readout == "ray" else None
        # Where the camera sees each target: the point loss's aim, on either readout.
        self.seen = self.rays if self.rays is not None or c.point_loss_weight == 0 or \
            spec.camera is None else CameraRays(spec)
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
        # The ray readout's head reads no coordinates: the camera places the point.
        head_in = (2 if self.rays is None else 0) + (value if reads_features else 0) + \
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

    def queries(self, conditions: Tensor) -> Tensor:
        """The Query vectors for one-hot conditions (B, C): (B, q, Ck + 2)."""
        batch = conditions.shape[0]
        parts = []
        if self.base_queries is not None:
            parts.append(self.base_queries.expand(batch, -1, -1))  # (B, q, Ck + 2)
        if self.query_mlp is not None:
            parts.append(self.query_mlp(conditions).view(batch, self.targets, -1))
        return torch.stack(parts).sum(dim=0)  # (B, q, Ck + 2)

    def attend(self, images: Tensor, queries: Tensor) -> Attention:
        """Selection and extraction: images (B, 3, H, W) in [0, 1], queries (B, q', Ck + 2)."""
        x = normalise_images(images, self.per_image)  # (B, 3, H, W)
        keys = self.key_net(x)  # (B, Ck + 2, h, w)
        values = self.value_net(x)  # (B, Cv, h, w)
        height, width = keys.shape[-2:]
        if self.similarity == "cosine":
            keys = unit(keys, dim=1)  # (B, Ck + 2, h, w), unit per cell
            queries = unit(queries, dim=-1)  # (B, q', Ck + 2)
            logits = torch.einsum("bchw,bqc->bqhw", keys, queries)  # (B, q', h, w) in [-1, 1]
        else:
            logits = torch.einsum("bchw,bqc->bqhw", keys, queries) / math.sqrt(height * width)
        heatmaps = softmax2d(logits, self.temperature)  # (B, q', h, w)
        grid = coordinate_grid(height, width, images.device)  # (2, h, w)
        return Attention(heatmaps, spatial_expectation(heatmaps, grid),  # (B, q', 2)
                         spatial_expectation(heatmaps, values))  # (B, q', Cv)

    def forward(self, images: Tensor, conditions: Tensor, queries: Tensor | None = None
                ) -> NetOutput:
        """Targets for images (B, 3, H, W) in [0, 1] under conditions (B, C) (or given Queries)."""
        attention = self.attend(images, self.queries(conditions) if queries is None else queries)
        batch, heads = attention.coords.shape[:2]
        parts = [attention.coords] if self.rays is None else []  # (B, q, 2)
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
            positions, turn = self.rays.read(attention.coords, place, self.scaler)
        rotations = lines = None
        if self.rotation is not None:  # (B, q, 3, 3), (B, q, 3, 4) | None
            rotations, lines = decode_rotation(out[..., self.place_size:], self.rotation, turn)
        types = None if self.type_head is None else self.type_head(attention.features)
        return NetOutput(positions, rotations, attention.coords, attention.heatmaps, lines,
                         types)  # types: (B, q, T) | None


class KqvModel(TorchModel):
    """The KQV attention model behind the :class:`PerceptionModel` interface.

    Build it for a dataset with :meth:`for_dataset`, train it with :meth:`fit`, then
    ``predict(image, condition)``; ``save``/``load`` a checkpoint folder. :meth:`queries` and
    :meth:`attend` expose the Queries, so a caller can steer the attention from outside.
    """

    name = "kqv"
    config_class = KqvConfig
    config: KqvConfig
    network: KqvNet

    def build_network(self) -> KqvNet:
        """The Key, Value, Query and head networks for this spec."""
        network = KqvNet(self.spec, self.config)
        network.scaler = self.scaler
        return network

    _steps_taken = 0  # training steps of the current fit, for the temperature warm-up
    _mirror: Mirror | None = None  # mirrors training samples (KqvConfig.mirror)

    def fit(self, dataset: Dataset, config: TrainConfig | None = None,
            progress: bool = True) -> TrainReport:
        """Trains as :meth:`TorchModel.fit` does, warming the temperature up first.

        The softmax temperature starts at :attr:`KqvConfig.warmup_temperature` and falls to
        :attr:`KqvConfig.temperature` over :attr:`KqvConfig.warmup_steps`; afterwards, and
        whatever happens during training, the network is left at ``temperature``. On the first
        fit, :attr:`KqvConfig.starts` initialisations train :attr:`KqvConfig.start_steps` steps
        each and the best goes on; ``config.steps`` counts its steps, and the report's wall
        time includes the dropped starts'.

        With a type head, :attr:`KqvConfig.type_steps` more steps then train it alone; the
        report chains the two phases (``"targets"``, ``"object types"``) and its ``final_loss``
        stays the targets'. A dataset that names no target's type trains no type phase.
        """
        config = config or TrainConfig()
        mirror = self.config.mirror
        if mirror is None:
            mirror = dataset.metadata.extra.get(MIRROR_FLAG) is True
        self._mirror = Mirror(self.spec, config.seed) if mirror else None
        try:
            pose = self._fit_pose(dataset, config, progress)
        finally:
            self.network.temperature = self.config.temperature
        if self.network.type_head is None or not (dataset.target_type_indices() >= 0).any():
            return pose
        types = train(self.network, self.type_loss, dataset,
                      replace(config, steps=self.config.type_steps), progress,
                      description=f"{self.name} {self.spec.task} [object types]",
                      parameters=self.network.type_head.parameters())
        chained = TrainReport.chain([pose, types], ("targets", "object types"))
        self.report = replace(chained, final_loss=pose.final_loss, config=config)
        return self.report

    def _fit_pose(self, dataset: Dataset, config: TrainConfig, progress: bool) -> TrainReport:
        """The pose training of :meth:`fit`: the starts, then the rest of the steps."""
        fresh = self.scaler is None  # a first fit may try several starts; a later one not
        if fresh:
            self.spec.check_dataset(dataset)
            self.scaler = LabelScaler.fit(dataset.labels[..., :3])
            self.network.scaler = self.scaler
        if not fresh or self.config.starts == 1 or config.steps <= self.config.start_steps:
            self._steps_taken = 0
            return super().fit(dataset, config, progress)
        start, spent_s = self._best_start(dataset, config, progress)
        rest = super().fit(dataset, replace(config, steps=config.steps - start.steps),
                           progress)  # the warm-up goes on from the step the start reached
        chained = TrainReport.chain([start, rest])
        self.report = replace(chained, config=config, wall_time_s=chained.wall_time_s + spent_s)
        return self.report

    def phases(self) -> list[Phase]:
        """One phase: the target loss on every parameter but the type head's (see :meth:`fit`)."""
        return [Phase("targets", self.batch_loss, self._pose_parameters())]

    def _pose_parameters(self) -> list[nn.Parameter]:
        """The network's parameters that the pose training moves: all but the type head's."""
        head = self.network.type_head
        skipped = set() if head is None else {id(p) for p in head.parameters()}
        return [p for p in self.network.parameters() if id(p) not in skipped]

    def _best_start(self, dataset: Dataset, config: TrainConfig, progress: bool
                    ) -> tuple[TrainReport, float]:
        """Trains :attr:`KqvConfig.starts` fresh networks briefly and keeps the best one.

        The starts train on the scenes :attr:`KqvConfig.start_holdout` leaves and are compared
        by their mean position error on the held-out ones (by training loss where nothing is
        held out). Returns the kept start's report and the wall time the dropped ones took [s].
        """
        short = replace(config, steps=self.config.start_steps)
        kept, held = split_scenes(dataset, self.config.start_holdout, config.seed)
        tried: list[tuple[float, float, int, KqvNet, TrainReport]] = []
        for number in range(self.config.starts):
            seed = self.config.seed if number == 0 else int(
                np.random.SeedSequence([self.config.seed, number]).generate_state(1)[0] >> 1)
            with torch.random.fork_rng(devices=[]):
                torch.manual_seed(seed)
                self.network = self.build_network()
            self._steps_taken = 0
            report = train(self.network, self.batch_loss, kept, short, progress,
                           description=f"{self.name} {self.spec.task} [start {number + 1}/"
                           f"{self.config.starts}]", parameters=self._pose_parameters())
            self.network.temperature = self.config.temperature
            held_cm = 0.0 if held is None else evaluate(self, held).mean_position_error_cm
            tried.append((held_cm, report.final_loss, number, self.network, report))
        _, _, _, self.network, kept_report = min(tried, key=lambda t: (t[0], t[1], t[2]))
        self._steps_taken = self.config.start_steps
        spent_s = sum(t[4].wall_time_s for t in tried) - kept_report.wall_time_s
        return kept_report, spent_s

    def batch_loss(self, batch: Batch) -> Tensor:
        """The target loss, at the temperature the warm-up has reached by this step.

        With :attr:`KqvConfig.mirror`, a random half of the batch is mirrored first.

        Where the dataset records its camera, plus :attr:`KqvConfig.point_loss_weight` times
        the squared distance (normalised image units) from each attention point to where the
        camera sees its target (the labelled position or grasp point, projected).
        """
        c = self.config
        done = min(1.0, (self._steps_taken + 1) / c.warmup_steps) if c.warmup_steps else 1.0
        self.network.temperature = c.warmup_temperature + done * (c.temperature -
                                                                  c.warmup_temperature)
        self._steps_taken += 1
        if self._mirror is not None:
            batch = self._mirror(batch)
        out = self.network(batch.images, batch.conditions)
        loss = self.target_loss(out, batch.labels, batch.present)
        camera = self.network.seen
        if camera is not None and c.point_loss_weight > 0 and out.points is not None:
            seen = camera.project(batch.labels[..., :3])  # (B, q, 2)
            loss = loss + c.point_loss_weight * present_mean(
                (out.points - seen).square().sum(-1), batch.present)
        return loss

    def type_loss(self, batch: Batch) -> Tensor:
        """The type head's cross-entropy on the frozen network's attended features.

        Targets of unknown type (index -1) count for nothing. The batch is mirrored as in
        :meth:`batch_loss` (a type is the same in the mirror); the network runs at its final
        temperature, as it predicts.
        """
        if self._mirror is not None:
            batch = self._mirror(batch)
        head, indices = self.network.type_head, batch.type_indices  # indices: (B, q)
        if head is None or indices is None:
            raise InvalidInputError("type_loss", "no type head or no type indices",
                                    "a network with a type head and a batch with type_indices")
        with torch.no_grad():  # the pose network stays as the pose training left it
            queries = self.network.queries(batch.conditions)  # (B, q, Ck + 2)
            features = self.network.attend(batch.images, queries).features  # (B, q, Cv)
        logits = head(features)  # (B, q, T)
        known = indices >= 0  # (B, q)
        if not known.any():
            return logits.sum() * 0.0  # no type known in this batch: nothing to learn
        return nn.functional.cross_entropy(logits[known], indices[known])  # (n, T) vs (n,)

    @torch.no_grad()
    def predict_batch(self, images: np.ndarray, conditions: np.ndarray,
                      queries: np.ndarray | None = None) -> list[Prediction]:
        """Predictions for uint8 images (B, H, W, 3) and conditions (B, C).

        ``queries`` (B, q, Ck + 2), when given, replaces the learned Queries (top-down control
        from outside; see :meth:`queries` for the learned ones).
        """
        if queries is None:
            return super().predict_batch(images, conditions)
        self.check_batch(images, conditions)
        given = self._check_queries(queries, len(images))
        out = self.network(images_to_tensor(images), torch.as_tensor(conditions).float(), given)
        return self.to_predictions(out, conditions)

    @torch.no_grad()
    def queries(self, conditions: np.ndarray) -> np.ndarray:
        """The learned Query vectors (B, q, Ck + 2) for one-hot conditions (B, C)."""
        return self.network.queries(torch.as_tensor(conditions).float()).numpy()

    @torch.no_grad()
    def attend(self, images: np.ndarray, queries: np.ndarray) -> dict[str, np.ndarray]:
        """Attention of uint8 images (B, H, W, 3) under any Queries (B, q', Ck + 2).

        Returns ``points_px`` (B, q', 2) (u right, v down), ``heatmaps`` (B, q', h, w) and
        ``features`` (B, q', Cv): where each Query looks and what it sees there.
        """
        self.check_batch(images, np.zeros((len(images), self.spec.condition_size)))
        attention = self.network.attend(images_to_tensor(images),
                                        self._check_queries(queries, len(images), any_q=True))
        points = normalised_to_pixels(attention.coords, self.spec.image_height_px,
                                      self.spec.image_width_px)
        return {"points_px": points.double().numpy(), "heatmaps": attention.heatmaps.numpy(),
                "features": attention.features.numpy()}

    def _check_queries(self, queries: np.ndarray, batch: int, any_q: bool = False) -> Tensor:
        size = self.config.key_dim + 2
        heads = np.shape(queries)[1] if any_q and np.ndim(queries) == 3 else self.spec.targets
        if np.ndim(queries) != 3 or np.shape(queries) != (batch, heads, size):
            raise InvalidInputError("queries", f"shape {np.shape(queries)}",
                                    f"shape ({batch}, {'q' if any_q else heads}, {size})")
        return torch.as_tensor(np.asarray(queries, dtype=np.float32))
