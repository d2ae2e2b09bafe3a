"""What every torch model here shares: predicting, the target loss, training phases, checkpoints.

A :class:`TorchModel` is a :class:`~perception.learning.learnable.LearnableModel` built around one
``nn.Module`` whose ``forward(images, conditions)`` returns a :class:`NetOutput`: the targets
in the label scaler's units, plus the attention points and heatmaps where the network has them.
A subclass names its hyper-parameter dataclass and builds its network; predicting, the loss on
the labels, ``fit`` (one :class:`Phase` or more, through :func:`perception.learning.train.train`),
``save`` and ``load`` are the same for all::

    class Tiny(TorchModel):
        name = "tiny"
        config_class = TinyConfig          # a frozen dataclass with a ``seed`` field

        def build_network(self) -> nn.Module:
            return TinyNet(self.spec, self.config)

Autoencoder baselines train in two phases (reconstruction first, then the head on the frozen
encoder): they override :meth:`TorchModel.phases`.
"""

from __future__ import annotations

import abc
import dataclasses
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any, ClassVar, NamedTuple, Self

import numpy as np
import torch
from torch import Tensor, nn

from perception.camera import Calibrations
from perception.interface import (
    ConditionKind,
    InvalidInputError,
    LabelKind,
    ModelInput,
    Prediction,
    Target,
)
from perception.learning.checkpoint import (
    CONFIG_FILE,
    CheckpointError,
    check_shapes,
    load_checkpoint,
    save_checkpoint,
)
from perception.learning.data import Dataset
from perception.learning.learnable import LearnableModel, ModelSpec
from perception.learning.rotations import axis_line_loss, rotation_from_6d, symmetric_chordal_loss
from perception.learning.torch_pieces import LabelScaler, images_to_tensor, normalised_to_pixels
from perception.learning.train import Batch, TrainConfig, TrainReport, train


class NetOutput(NamedTuple):
    """A network's output for a batch (tensors, batch first)."""

    positions: Tensor  # (B, q, 3) in the label scaler's units
    rotations: Tensor | None  # (B, q, 3, 3) proper rotations; None for position labels
    points: Tensor | None = None  # (B, p, 2) attention points, (x, y) in [-1, 1]; None: none
    heatmaps: Tensor | None = None  # (B, p, h, w), each summing to 1; None where it has none
    rotation_lines: Tensor | None = None  # (B, q, 3, 4) axis-line codes; None: the loss reads
    # the rotations (see perception.learning.rotations)
    type_logits: Tensor | None = None  # (B, q, T) over the spec's object_types; None: the
    # network states no type


def reads_calibration(network: nn.Module) -> bool:
    """Whether ``network`` reads positions through the camera (a ray readout: ``rays``).

    Such a model declares :attr:`ModelInput.CAMERA`: each frame's calibration is what it reads
    through, so a camera moved and re-calibrated after training costs nothing.
    """
    return getattr(network, "rays", None) is not None


def pose_size(label_kind: LabelKind) -> int:
    """Outputs per target a head predicts: 3 (position) or 9 (position + 6-D rotation)."""
    return 3 if label_kind is LabelKind.POSITION else 9


def split_pose(out: Tensor) -> tuple[Tensor, Tensor | None]:
    """A head's output (B, q, 3 | 9) -> positions (B, q, 3) and rotations (B, q, 3, 3) | None."""
    rotations = rotation_from_6d(out[..., 3:]) if out.shape[-1] == 9 else None
    return out[..., :3], rotations


def present_mean(values: Tensor, present: Tensor | None) -> Tensor:
    """The mean of per-target ``values`` (B, q) over the targets ``present`` (B, q) marks.

    With every target present (or ``present`` None) it is the plain mean, to the bit.
    """
    if present is None or bool(present.all()):
        return values.mean()
    return (values * present).sum() / present.sum().clamp(min=1)


class Phase(NamedTuple):
    """One stage of training: the loss to lower and the parameters that lower it."""

    name: str
    loss: Callable[[Batch], Tensor]
    parameters: Iterable[nn.Parameter]


class TorchModel(LearnableModel):
    """A learnable model with one torch network; see the module docstring for a subclass.

    Args:
        spec: What the model is built for (label kind, q, condition, image size).
        config: The hyper-parameters, an instance of :attr:`config_class`; None: its defaults.
        scaler: Maps labels to the network's units; None until :meth:`fit` sets it.

    """

    config_class: ClassVar[type[Any]]
    label_kind = LabelKind.POSITION  # replaced per instance by the spec's

    def __init__(self, spec: ModelSpec, config: Any = None,
                 scaler: LabelScaler | None = None) -> None:
        if config is None:
            config = self.config_class()
        if not isinstance(config, self.config_class):
            raise InvalidInputError("config", type(config).__name__,
                                    f"a {self.config_class.__name__} for model {self.name!r}")
        self.spec, self.config, self.scaler = spec, config, scaler
        self.label_kind = spec.label_kind
        self.report: TrainReport | None = None
        # Where settings came from (``model_config_file``: the file that set them): saved in
        # the checkpoint's training record beside the report, so a reader can trace them.
        self.provenance: dict[str, Any] = {}
        self.network = self.seeded_network(config.seed).eval()
        if reads_calibration(self.network):  # a trial gives it the frame's calibration
            self.inputs = self.inputs | {ModelInput.CAMERA}

    @abc.abstractmethod
    def build_network(self) -> nn.Module:
        """The network for ``self.spec`` and ``self.config``; forward returns a NetOutput."""

    def seeded_network(self, seed: int) -> nn.Module:
        """:meth:`build_network` under ``seed`` (global RNG left alone), weights channels-last.

        Images reach a network channels-last in memory (:func:`images_to_tensor` permutes
        (B, H, W, 3) pixels); with the convolution weights laid out alike, oneDNN's kernels
        skip their layout conversions: a yumi ``kqv`` step 14 % faster on one CPU thread, the
        same arithmetic (``benchmarks/bench_train.py``). The checkpoint stores them contiguous.
        """
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(seed)
            network = self.build_network()
        for weight in network.parameters():
            if weight.dim() == 4:
                weight.data = weight.data.contiguous(memory_format=torch.channels_last)
        return network

    @classmethod
    def for_dataset(cls, dataset: Dataset, config: Any = None) -> Self:
        """A fresh model for ``dataset``'s task (its label kind, q, condition and image size)."""
        return cls(ModelSpec.from_metadata(dataset.metadata), config)

    # training

    def phases(self) -> list[Phase]:
        """The training stages, in order; by default one: every parameter on the target loss."""
        return [Phase("targets", self.batch_loss, self.network.parameters())]

    def fit(self, dataset: Dataset, config: TrainConfig | None = None,
            progress: bool = True) -> TrainReport:
        """Trains on ``dataset``; the label scaler comes from its labels on the first fit.

        Each :meth:`phases` stage runs ``config.steps`` steps; the report chains them and
        names each in its ``phases``, with its wall time.
        """
        self.spec.check_dataset(dataset)
        if self.scaler is None:
            self.scaler = LabelScaler.fit(dataset.labels[..., :3])
        config = config or TrainConfig()
        phases = self.phases()
        reports = [train(self.network, phase.loss, dataset, config, progress,
                         description=f"{self.name} {self.spec.task}" +
                         (f" [{phase.name}]" if len(phases) > 1 else ""),
                         parameters=phase.parameters) for phase in phases]
        self.report = TrainReport.chain(reports, [phase.name for phase in phases])
        return self.report

    def batch_loss(self, batch: Batch) -> Tensor:
        """The target loss of the network's prediction for ``batch``."""
        return self.target_loss(self.network(batch.images, batch.conditions), batch.labels,
                                batch.present)

    def target_loss(self, out: NetOutput, labels: Tensor, present: Tensor | None = None
                    ) -> Tensor:
        """Squared position error (scaled units) + weighted rotation loss, over present targets.

        The position term is the squared Euclidean distance in the scaler's units, so it stays
        proportional to the error in metres the paper reports; the rotation term, the symmetric
        chordal loss or, for a head with axis-line codes, the loss on those codes, counts a half
        turn about the TCP's approach axis as no error (the same parallel-gripper grasp).
        ``present`` (B, q) leaves out targets no longer in the image (:attr:`Batch.present`).
        """
        target = self._scaler().normalise(labels[..., :3])  # (B, q, 3)
        loss = present_mean((out.positions - target).square().sum(dim=-1), present)
        if out.rotations is not None:
            rotation = labels[..., 3:].unflatten(-1, (3, 3))  # (B, q, 3, 3), row-major
            rotation_loss = symmetric_chordal_loss(out.rotations, rotation) \
                if out.rotation_lines is None else axis_line_loss(out.rotation_lines, rotation)
            loss = loss + self.config.rotation_loss_weight * present_mean(rotation_loss, present)
        return loss

    # predicting

    @torch.no_grad()
    def predict_batch(self, images: np.ndarray, conditions: np.ndarray,
                      depths_m: np.ndarray | None = None, *, cameras: Calibrations = None
                      ) -> list[Prediction]:
        """Predictions for uint8 images (B, H, W, 3) and condition vectors (B, C), in order.

        ``depths_m``: ignored; a network that reads depth (kqv's) is given it by its model.
        ``cameras``: each image's calibration, for a network that reads positions through the
        camera (:func:`reads_calibration`; it is given them as ``cameras=``); None: the spec's.
        """
        self.check_batch(images, conditions)
        given = {} if cameras is None else {"cameras": cameras}
        out = self.network(images_to_tensor(images), torch.as_tensor(conditions).float(), **given)
        return self.to_predictions(out, conditions)

    def to_predictions(self, out: NetOutput, conditions: np.ndarray) -> list[Prediction]:
        """The network's output for a batch as one :class:`Prediction` per image.

        Each target states its object type: the condition's under an object-type condition,
        else the type the network's type logits give most weight, where it has them.
        """
        spec = self.spec
        positions = self._scaler().denormalise(out.positions).double().numpy()  # (B, q, 3) [m]
        rotations = None if out.rotations is None else out.rotations.double().numpy()
        points = None if out.points is None else normalised_to_pixels(
            out.points, spec.image_height_px, spec.image_width_px).double().numpy()  # (B, p, 2)
        heatmaps = None if out.heatmaps is None else out.heatmaps.numpy()  # (B, p, h, w)
        seen = None if out.type_logits is None else out.type_logits.argmax(dim=-1).numpy()
        predictions = []
        for b in range(len(positions)):
            object_types: list[str | None] = [None] * spec.targets
            if spec.condition_kind is ConditionKind.OBJECT_TYPE:
                object_types = [spec.condition_choices[int(np.argmax(conditions[b]))]] * \
                    spec.targets
            elif seen is not None:  # (B, q) indices into spec.object_types
                object_types = [spec.object_types[int(i)] for i in seen[b]]
            targets = tuple(Target(positions[b, i], None if rotations is None else
                                   rotations[b, i], object_types[i]) for i in range(spec.targets))
            predictions.append(Prediction(
                targets, np.zeros((0, 2)) if points is None else points[b],
                None if heatmaps is None else heatmaps[b]))
        return predictions

    # checkpoints

    def save(self, path: str | Path) -> Path:
        """Writes the checkpoint folder ``path`` (weights.safetensors + config.json)."""
        config: dict[str, Any] = {
            "spec": self.spec.to_json(), "hyperparameters": dataclasses.asdict(self.config),
            "label_scaler": self._scaler().to_json(),
            "training": None if self.report is None
            else self.report.to_json() | self.provenance,
        }
        return save_checkpoint(path, self.name, config, self.network.state_dict())

    @classmethod
    def load(cls, path: str | Path) -> Self:
        """The model saved at ``path``; refuses a damaged or mismatched checkpoint."""
        checkpoint = load_checkpoint(path, cls.name)
        data = checkpoint.config
        try:
            model = cls(ModelSpec.from_json(data["spec"]),
                        cls.config_class(**cls.hyperparameters_from(
                            data["hyperparameters"], frozenset(checkpoint.tensors))),
                        LabelScaler.from_json(data["label_scaler"]))
        except (KeyError, TypeError, ValueError) as error:
            raise CheckpointError(checkpoint.folder / CONFIG_FILE, f"cannot rebuild the model "
                                  f"({type(error).__name__}: {error})") from error
        expected = model.network.state_dict()
        checkpoint = dataclasses.replace(checkpoint, tensors=cls.tensors_from(
            checkpoint.tensors, expected))
        check_shapes(checkpoint, expected)
        model.network.load_state_dict(checkpoint.tensors)
        return model

    @classmethod
    def tensors_from(cls, saved: dict[str, torch.Tensor], expected: Mapping[str, torch.Tensor]
                     ) -> dict[str, torch.Tensor]:
        """A checkpoint's tensors, older ones completed.

        Tensors a later version of the network added get the value that reads as before them
        (from ``expected``, the network's own); by default, as saved.
        """
        return saved

    @classmethod
    def hyperparameters_from(cls, saved: dict[str, Any], tensors: frozenset[str] = frozenset()
                             ) -> dict[str, Any]:
        """The keyword arguments of :attr:`config_class` a checkpoint's saved values give.

        A model whose later versions add a setting (or resolve ``"auto"`` otherwise) that
        changes older checkpoints' networks names here the value those checkpoints were trained
        with, from the saved values and the names of the saved ``tensors``; by default, as saved.
        """
        return saved

    def _scaler(self) -> LabelScaler:
        if self.scaler is None:
            raise InvalidInputError("model", "untrained (no label scaler)", "fit() or load() first")
        return self.scaler
