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
inference.

The image is read at full size (128 x 128) but the first two layers of each FCN have stride 2
(:attr:`KqvConfig.stride`), so the heatmaps are 32 x 32: four times fewer cells to attend over
and sixteen times less work per layer, which keeps training on two CPU cores within minutes;
``a_coord`` is an expectation, so it still resolves positions between cells.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import NamedTuple, cast

import numpy as np
import torch
from torch import Tensor, nn

from perception.data import Dataset
from perception.interface import ConditionKind, InvalidInputError, LabelKind, Prediction
from perception.learnable import ModelSpec, check_choices
from perception.models.base import (
    MLP,
    CoordConv,
    LabelScaler,
    coordinate_grid,
    images_to_tensor,
    normalised_to_pixels,
    rotation_from_6d,
    softmax2d,
    spatial_expectation,
)
from perception.models.torch_model import NetOutput, TorchModel, pose_size, split_pose
from perception.train import Batch, TrainConfig, TrainReport, train

QUERY_MODES = ("auto", "base", "conditioned", "conditioned+base")
READOUTS = ("auto", "mlp", "ray")


@dataclass(frozen=True)
class KqvConfig:
    """Hyper-parameters of the KQV attention model.

    Args:
        channels: Output channels of the first two conv layers of FCN1 and of FCN2; few in the
            first (it runs at the finest resolution), more in the second.
        key_dim: Ck, the Key's learned channels; Keys and Queries have Ck + 2 entries (the two
            coordinate channels ride along, so a Query can prefer a place as well as a look).
        value_dim: Cv, the Feature Value's channels (the length of ``a_feat``).
        stride: Downsampling from image to heatmap, 1, 2 or 4 (stride 2 in the first one or two
            layers of each FCN): 4 turns 128 x 128 images into 32 x 32 heatmaps.
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
            steps, the one with the lowest training loss by then goes on for the rest of the
            steps and the others are dropped. Even warmed up, a start now and then leaves a
            Query's heatmap spread over the whole image, where the loss sits on a plateau for
            hundreds of steps (paper-sim ``single`` 100 scenes, seed 1: 0.55 until step 700,
            10.0 cm). By the end of the temperature warm-up a good start has its loss a decade
            lower than such a one, so the choice is cheap: 1: one start, as before.
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
        head_width: Width of the head MLP's two hidden layers.
        rotation_loss_weight: Weight of the chordal rotation loss against the position loss
            (squared distance in scaled units); 0.1 weighs 1 cm (at a 0.2 m label scale) like
            about 6 degrees of rotation.
        seed: Seeds the initial weights.

    """

    channels: tuple[int, int] = (16, 32)
    key_dim: int = 16
    value_dim: int = 16
    stride: int = 4
    similarity: str = "cosine"
    temperature: float = 0.1
    warmup_temperature: float = 0.3
    warmup_steps: int = 300
    starts: int = 3
    start_steps: int = 300
    query_mode: str = "auto"
    head_features: bool | None = None
    readout: str = "auto"
    head_width: int = 64
    rotation_loss_weight: float = 0.1
    seed: int = 0

    def __post_init__(self) -> None:
        channels = tuple(self.channels) if isinstance(self.channels, list | tuple) else ()
        if len(channels) != 2 or not all(isinstance(c, int) and c >= 1 for c in channels):
            raise InvalidInputError("channels", self.channels, "two integers >= 1")
        object.__setattr__(self, "channels", channels)  # a JSON list reads back as the tuple
        for name in ("key_dim", "value_dim", "head_width", "warmup_steps", "starts",
                     "start_steps"):
            value = getattr(self, name)
            least = 0 if name == "warmup_steps" else 1
            if not isinstance(value, int) or isinstance(value, bool) or value < least:
                raise InvalidInputError(name, value, f"an integer >= {least}")
        check_choices("stride", self.stride, (1, 2, 4))
        check_choices("query_mode", self.query_mode, QUERY_MODES)
        check_choices("similarity", self.similarity, ("cosine", "dot"))
        check_choices("readout", self.readout, READOUTS)
        for name in ("temperature", "warmup_temperature"):
            if not (math.isfinite(getattr(self, name)) and getattr(self, name) > 0):
                raise InvalidInputError(name, getattr(self, name), "a finite value > 0")
        if not (math.isfinite(self.rotation_loss_weight) and self.rotation_loss_weight >= 0):
            raise InvalidInputError("rotation_loss_weight", self.rotation_loss_weight,
                                    "a finite value >= 0")
        if self.head_features not in (None, True, False):
            raise InvalidInputError("head_features", self.head_features, "None, True or False")
        if not isinstance(self.seed, int) or self.seed < 0:
            raise InvalidInputError("seed", self.seed, "an integer >= 0")


class Attention(NamedTuple):
    """What the heads attend to (tensors, batch first)."""

    heatmaps: Tensor  # (B, q, h, w) M, each map sums to 1
    coords: Tensor  # (B, q, 2) a_coord, (x, y) in [-1, 1]
    features: Tensor  # (B, q, Cv) a_feat


class KqvNet(nn.Module):
    """The network: FCN1 (Key), FCN2 (Feature Value), the Queries and the head MLP."""

    def __init__(self, spec: ModelSpec, config: KqvConfig) -> None:
        super().__init__()
        c, key, value = config, config.key_dim, config.value_dim
        (wide1, wide2), hidden = config.channels, config.channels[1]
        first, second = {1: (1, 1), 2: (2, 1), 4: (2, 2)}[c.stride]
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
        self.readout = c.readout
        if self.readout == "auto":
            self.readout = "ray" if spec.label_kind is LabelKind.GRASP_POSE and \
                spec.camera is not None else "mlp"
        self.rays = CameraRays(spec) if self.readout == "ray" else None
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
        head_out = pose_size(spec.label_kind) + (1 if self.rays is not None else 0)
        self.head = MLP((head_in, c.head_width, c.head_width, head_out))

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
        x = (images - 0.5) / 0.25  # (B, 3, H, W), roughly zero mean, unit spread
        keys = self.key_net(x)  # (B, Ck + 2, h, w)
        values = self.value_net(x)  # (B, Cv, h, w)
        height, width = keys.shape[-2:]
        if self.similarity == "cosine":
            keys = nn.functional.normalize(keys, dim=1)  # (B, Ck + 2, h, w), unit per cell
            queries = nn.functional.normalize(queries, dim=-1)  # (B, q', Ck + 2)
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
        out = self.head(torch.cat(parts, dim=-1))  # (B, q, 3|9 (+1 with rays))
        if self.rays is None:
            positions, rotations = split_pose(out)  # (B, q, 3), (B, q, 3, 3) | None
        else:
            if self.scaler is None:
                raise InvalidInputError("scaler", None, "a LabelScaler before the ray readout "
                                        "runs (KqvModel sets it on fit and load)")
            positions, rotations = self.rays.read(attention.coords, out, self.scaler)
        return NetOutput(positions, rotations, attention.coords, attention.heatmaps)


class CameraRays(nn.Module):
    """The ray readout: a target's pose from its attention point, through the calibrated camera.

    The head's output per target is ``(height, offset (3), rotation (6-D, with grasp labels))``
    in network units; the target is where the point's ray meets the plane z = height, plus the
    offset, which, like the rotation, is expressed in the frame turned about z toward that
    point's bearing from the world origin (the robot base).
    """

    tangents: Tensor  # (2,) tan of the half fields of view, horizontal and vertical
    basis: Tensor  # (3, 3) world from camera
    origin: Tensor  # (3,) the optical centre [m]

    def __init__(self, spec: ModelSpec) -> None:
        super().__init__()
        camera = spec.camera
        if camera is None:
            raise InvalidInputError("readout", "ray", "'mlp' or 'auto' for a dataset that "
                                    "records no camera")
        if (camera.height_px, camera.width_px) != (spec.image_height_px, spec.image_width_px):
            raise InvalidInputError("camera", f"{camera.width_px} x {camera.height_px} px",
                                    f"the images' {spec.image_width_px} x "
                                    f"{spec.image_height_px} px for readout 'ray'")
        self.camera = camera
        tangents = torch.tensor(camera.tan_half_fov, dtype=torch.float32)  # (2,)
        basis = torch.tensor(camera.world_from_camera, dtype=torch.float32)  # (3, 3)
        origin = torch.tensor(camera.position_m, dtype=torch.float32)  # (3,)
        self.register_buffer("tangents", tangents, persistent=False)  # rebuilt from the spec
        self.register_buffer("basis", basis, persistent=False)
        self.register_buffer("origin", origin, persistent=False)

    def read(self, coords: Tensor, out: Tensor, scaler: LabelScaler
             ) -> tuple[Tensor, Tensor | None]:
        """Targets from points (B, q, 2) in [-1, 1] and head outputs (B, q, 4 | 10).

        Returns positions (B, q, 3) in the scaler's units and rotations (B, q, 3, 3) | None.
        """
        camera = self.camera
        pixels = normalised_to_pixels(coords, camera.height_px, camera.width_px)  # (B, q, 2)
        ndc_x, ndc_y = camera.pixels_to_ndc(pixels[..., 0], pixels[..., 1])  # (B, q) each
        local = torch.stack([ndc_x * self.tangents[0], ndc_y * self.tangents[1],
                             -torch.ones_like(ndc_x)], dim=-1)  # (B, q, 3), camera frame
        direction = local @ self.basis.T  # (B, q, 3), world frame
        centre = out.new_tensor(scaler.centre_m)  # (3,)
        height_m = centre[2] + scaler.scale_m * out[..., 0]  # (B, q)
        down = direction[..., 2].clamp(max=-1e-3)  # (B, q); rays that miss the plane do not
        point = self.origin + direction * ((height_m - self.origin[2]) / down)[..., None]
        bearing = torch.atan2(point[..., 1], point[..., 0])  # (B, q)
        cos, sin, zero, one = (bearing.cos(), bearing.sin(), torch.zeros_like(bearing),
                               torch.ones_like(bearing))
        turn = torch.stack([cos, -sin, zero, sin, cos, zero, zero, zero, one],
                           dim=-1).unflatten(-1, (3, 3))  # (B, q, 3, 3) about z
        offset_m = scaler.scale_m * (turn @ out[..., 1:4, None])[..., 0]  # (B, q, 3)
        positions = (point + offset_m - centre) / scaler.scale_m  # (B, q, 3)
        rotations = None if out.shape[-1] == 4 else turn @ rotation_from_6d(out[..., 4:])
        return positions, rotations


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

    def fit(self, dataset: Dataset, config: TrainConfig | None = None,
            progress: bool = True) -> TrainReport:
        """Trains as :meth:`TorchModel.fit` does, warming the temperature up first.

        The softmax temperature starts at :attr:`KqvConfig.warmup_temperature` and falls to
        :attr:`KqvConfig.temperature` over :attr:`KqvConfig.warmup_steps`; afterwards, and
        whatever happens during training, the network is left at ``temperature``. On the first
        fit, :attr:`KqvConfig.starts` initialisations train :attr:`KqvConfig.start_steps` steps
        each and the best goes on; ``config.steps`` counts its steps, and the report's wall
        time includes the dropped starts'.
        """
        config = config or TrainConfig()
        try:
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
            self.report = replace(chained, config=config,
                                  wall_time_s=chained.wall_time_s + spent_s)
            return self.report
        finally:
            self.network.temperature = self.config.temperature

    def _best_start(self, dataset: Dataset, config: TrainConfig, progress: bool
                    ) -> tuple[TrainReport, float]:
        """Trains :attr:`KqvConfig.starts` fresh networks briefly and keeps the best one.

        Returns the kept start's report and the wall time the dropped ones took [s].
        """
        short = replace(config, steps=self.config.start_steps)
        tried: list[tuple[float, int, KqvNet, TrainReport]] = []
        for number in range(self.config.starts):
            seed = self.config.seed if number == 0 else int(
                np.random.SeedSequence([self.config.seed, number]).generate_state(1)[0] >> 1)
            with torch.random.fork_rng(devices=[]):
                torch.manual_seed(seed)
                self.network = self.build_network()
            self._steps_taken = 0
            report = train(self.network, self.batch_loss, dataset, short, progress,
                           description=f"{self.name} {self.spec.task} [start {number + 1}/"
                           f"{self.config.starts}]")
            tried.append((report.final_loss, number, self.network, report))
        _, _, self.network, kept = min(tried, key=lambda t: (t[0], t[1]))
        self._steps_taken = self.config.start_steps
        spent_s = sum(t[3].wall_time_s for t in tried) - kept.wall_time_s
        return kept, spent_s

    def batch_loss(self, batch: Batch) -> Tensor:
        """The target loss, at the temperature the warm-up has reached by this step."""
        c = self.config
        done = min(1.0, (self._steps_taken + 1) / c.warmup_steps) if c.warmup_steps else 1.0
        self.network.temperature = c.warmup_temperature + done * (c.temperature -
                                                                  c.warmup_temperature)
        self._steps_taken += 1
        return super().batch_loss(batch)

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
