"""The one training loop every learnable model uses: seeded batches, Adam, photometric noise.

A model hands :func:`train` its network and a ``batch_loss(batch) -> loss`` function; the loop
draws batches, augments them, steps the optimiser and reports. Read top to bottom::

    config = TrainConfig(steps=1000, batch_size=16)
    report = train(network, model.batch_loss, dataset, config)

Augmentation is photometric only (brightness, contrast, colour gain, pixel noise): no label in
the world frame fits a shifted or cropped image. Why, and the one flip a model may add
(:mod:`perception.learning.mirror`, in ``kqv``'s ``batch_loss``):
``docs/decisions/kqv.md#mirror-flip``.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import asdict, dataclass
from typing import Any, NamedTuple

import numpy as np
import torch
from torch import Tensor, nn
from tqdm import tqdm

from perception.interface import ConditionKind, InvalidInputError, PerceptionError
from perception.learning.data import Dataset
from perception.learning.torch_pieces import images_to_tensor

BRIGHTNESS = (0.7, 1.3)  # image gain: the yumi tasks light scenes at 0.3-1.0 brightness
CONTRAST = (0.8, 1.2)  # scales each image about its mean grey level
COLOUR_GAIN = (0.9, 1.1)  # per channel: small, so a red mug stays red and a green sponge green
NOISE_STD = 0.02  # per pixel and channel, of the [0, 1] range: sensor noise
_RGB_TO_YIQ = torch.tensor([[0.299, 0.587, 0.114],
                            [0.596, -0.274, -0.322],
                            [0.211, -0.523, 0.312]])
"""NTSC YIQ: luma Y and the two chroma axes I, Q; a turn in the IQ plane turns every hue alike
and keeps each pixel's luma (the usual hue jitter of colour augmentation)."""


class TrainingError(PerceptionError):
    """Training that cannot go on (e.g. the loss became NaN); the message says what to change."""


@dataclass(frozen=True)
class TrainConfig:
    """How to train a learnable model.

    Args:
        steps: Optimiser steps.
        batch_size: Samples per step; a dataset smaller than this gives all its samples each step.
        learning_rate: Adam's step size at the start.
        lr_schedule: ``"cosine"`` decays the rate to 0 over ``steps`` (fine final precision with
            few samples); ``"constant"`` keeps it.
        weight_decay: Adam's L2 penalty on every parameter.
        seed: Seeds batch order (numpy) and augmentation (torch); the weights' initial values
            come from the model's own seed.
        augment: Photometric augmentation on or off (see the module docstring); with it, a
            sentence's embedding is jittered too (``sentence_noise``).
        hue_jitter: With ``augment``, each training image's hues are also turned by an angle
            drawn uniformly in [-it, it] of a full turn (0.5: any hue), its luma kept: a model
            then cannot tell objects apart by hue, as in a world of many colourways
            (``docs/decisions/appearance.md``). 0, the default: no turn, and the training draws
            exactly what it drew before the option existed.
        sentence_noise: Under a text condition, Gaussian noise of this standard deviation per
            dimension is added to each embedding, which is then made unit length again (0.05:
            a cosine of about 0.7 with the sentence's). For a model that reads the embedding
            itself, so it answers alike near each training sentence (kqv's ``"embedding"``
            reading trained with 0.05). 0, the default: kqv reads a sentence by prototypes,
            where noise only makes some training sentences read as another target
            (``docs/decisions/open-conditions.md``).
        device: Torch device, ``"cpu"`` (the project's target) or e.g. ``"cuda"``.
        threads: CPU threads for torch; None: :func:`default_threads` (OMP_NUM_THREADS, else
            the cores this process may run on).
        log_every: Steps between two points of the loss curve.

    """

    steps: int = 1000
    batch_size: int = 16
    learning_rate: float = 2e-3
    lr_schedule: str = "cosine"
    weight_decay: float = 0.0
    seed: int = 0
    augment: bool = True
    hue_jitter: float = 0.0
    sentence_noise: float = 0.0
    device: str = "cpu"
    threads: int | None = None
    log_every: int = 25

    def __post_init__(self) -> None:
        for name in ("steps", "batch_size", "log_every"):
            value = getattr(self, name)
            if not isinstance(value, int) or isinstance(value, bool) or value < 1:
                raise InvalidInputError(name, value, "an integer >= 1")
        if not isinstance(self.seed, int) or self.seed < 0:
            raise InvalidInputError("seed", self.seed, "an integer >= 0")
        if not (math.isfinite(self.learning_rate) and self.learning_rate > 0):
            raise InvalidInputError("learning_rate", self.learning_rate, "a finite value > 0")
        if not (isinstance(self.hue_jitter, int | float) and 0.0 <= self.hue_jitter <= 0.5):
            raise InvalidInputError("hue_jitter", self.hue_jitter, "a share of a turn in [0, 0.5]")
        if not (math.isfinite(self.sentence_noise) and self.sentence_noise >= 0):
            raise InvalidInputError("sentence_noise", self.sentence_noise, "a finite value >= 0")
        if not (math.isfinite(self.weight_decay) and self.weight_decay >= 0):
            raise InvalidInputError("weight_decay", self.weight_decay, "a finite value >= 0")
        if self.lr_schedule not in ("cosine", "constant"):
            raise InvalidInputError("lr_schedule", self.lr_schedule, "'cosine' or 'constant'")
        if self.threads is not None and (not isinstance(self.threads, int) or self.threads < 1):
            raise InvalidInputError("threads", self.threads, "None or an integer >= 1")
        try:
            torch.device(self.device)
        except RuntimeError:
            raise InvalidInputError("device", self.device, "a torch device such as 'cpu'") from None


class Batch(NamedTuple):
    """One training batch, as a model's ``batch_loss`` receives it."""

    images: Tensor  # (B, 3, H, W) float32 in [0, 1], augmented
    conditions: Tensor  # (B, C) float32 condition vectors (one-hot, embeddings, pixels)
    labels: Tensor  # (B, q, D) float32, as the dataset holds them (not yet scaled)
    type_indices: Tensor | None = None  # (B, q) int64: each target's type in the dataset's
    # object_types (Dataset.target_type_indices), -1 unknown; None: not given
    present: Tensor | None = None  # (B, q) bool: the target is in the image
    # (Dataset.target_present); None: every target is
    depths_m: Tensor | None = None  # (B, H, W) float32 depth [m] of each image (0 or inf:
    # none), where the dataset keeps it (Dataset.depths_m); None where it does not


class PhaseSummary(NamedTuple):
    """One named phase of a training: its length, where its loss ended, and its wall time [s]."""

    name: str
    steps: int
    final_loss: float
    wall_time_s: float = 0.0


@dataclass(frozen=True)
class TrainReport:
    """How training went.

    Args:
        steps: Optimiser steps taken.
        samples: Training samples in the dataset.
        final_loss: Mean loss over the last ``log_every`` steps; where phases were chained, the
            last phase's, unless the model keeps its target loss's (kqv's object-type phase
            trains a side head after the targets: ``final_loss`` stays the targets').
        losses: (step, mean loss over the ``log_every`` steps up to it) pairs: the loss curve.
        wall_time_s: Wall time of the loop [s].
        threads: CPU threads torch used.
        config: The configuration trained with.
        phases: Each phase's name, steps and final loss, in order, where the training ran in
            named phases; () for a single run.

    """

    steps: int
    samples: int
    final_loss: float
    losses: tuple[tuple[int, float], ...]
    wall_time_s: float
    threads: int
    config: TrainConfig
    phases: tuple[PhaseSummary, ...] = ()

    def to_json(self) -> dict[str, Any]:
        """The report as JSON-able data."""
        data = asdict(self)
        data["losses"] = [list(point) for point in self.losses]
        data["phases"] = [phase._asdict() for phase in self.phases]
        return data

    @classmethod
    def chain(cls, reports: Sequence[TrainReport], names: Sequence[str] = ()) -> TrainReport:
        """One report for phases trained one after the other: steps and times add up.

        The loss curve runs on across phases (a later phase's steps follow the earlier ones');
        its losses are each phase's own, so the curve jumps where a phase changes its loss.
        ``names``, one per report, name the phases in :attr:`phases` (a report that has
        phases of its own brings those instead); () records none.
        """
        if not reports:
            raise InvalidInputError("reports", "none", "at least one training report")
        if names and len(names) != len(reports):
            raise InvalidInputError("names", list(names), f"one per report ({len(reports)})")
        losses, offset = [], 0
        for report in reports:
            losses += [(offset + step, loss) for step, loss in report.losses]
            offset += report.steps
        last = reports[-1]
        phases: list[PhaseSummary] = []
        for name, report in zip(names, reports, strict=True) if names else ():
            phases += report.phases or [PhaseSummary(name, report.steps, report.final_loss,
                                                     report.wall_time_s)]
        return cls(offset, last.samples, last.final_loss, tuple(losses),
                   sum(r.wall_time_s for r in reports), last.threads, last.config, tuple(phases))


def available_threads() -> int:
    """CPU cores this process may run on (its affinity mask, not the machine's total)."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


def default_threads() -> int:
    """Torch threads of a training that names none.

    ``OMP_NUM_THREADS`` where it is set (the limit torch itself reads: one a process where
    several share the cores, as ``make test``'s workers do; of an OpenMP list such as ``4,2``
    the first, the outer level), else every core this process may run on.
    """
    limit = os.environ.get("OMP_NUM_THREADS", "").split(",")[0].strip()
    if not limit:
        return available_threads()
    if not limit.isdigit() or int(limit) < 1:
        raise InvalidInputError("OMP_NUM_THREADS", limit, "unset, or an integer >= 1 (or a "
                                "list of them, the first taken)")
    return min(int(limit), available_threads())


def photometric_augment(images: Tensor, generator: torch.Generator,
                        hue_jitter: float = 0.0) -> Tensor:
    """Random brightness, contrast, colour gain and noise on images (B, 3, H, W) in [0, 1].

    ``hue_jitter`` > 0: then each image's hues turned by up to that share of a turn either way
    (:attr:`TrainConfig.hue_jitter`), drawn after the rest, so 0 draws what it always drew.
    """
    batch = images.shape[0]

    def uniform(low_high: tuple[float, float], *shape: int) -> Tensor:
        low, high = low_high
        return torch.rand(*shape, generator=generator).to(images) * (high - low) + low

    mean = images.mean(dim=(1, 2, 3), keepdim=True)  # (B, 1, 1, 1)
    images = (images - mean) * uniform(CONTRAST, batch, 1, 1, 1) + mean  # (B, 3, H, W)
    images = images * uniform(BRIGHTNESS, batch, 1, 1, 1) * uniform(COLOUR_GAIN, batch, 3, 1, 1)
    noise = torch.randn(images.shape, generator=generator).to(images) * NOISE_STD
    images = (images + noise).clamp_(0.0, 1.0)  # (B, 3, H, W)
    if hue_jitter > 0.0:
        images = turn_hues(images, 2.0 * math.pi * uniform((-hue_jitter, hue_jitter), batch))
    return images


def turn_hues(images: Tensor, angles_rad: Tensor) -> Tensor:
    """Each image (B, 3, H, W) in [0, 1] with its hues turned by its angle (B,), luma kept."""
    cos, sin = torch.cos(angles_rad), torch.sin(angles_rad)  # (B,)
    turn = torch.zeros(len(angles_rad), 3, 3).to(images)  # (B, 3, 3) in YIQ
    turn[:, 0, 0] = 1.0
    turn[:, 1, 1], turn[:, 1, 2], turn[:, 2, 1], turn[:, 2, 2] = cos, -sin, sin, cos
    to_yiq = _RGB_TO_YIQ.to(images)
    matrices = torch.linalg.inv(to_yiq) @ turn @ to_yiq  # (B, 3, 3) in RGB
    return torch.einsum("bij,bjhw->bihw", matrices, images).clamp_(0.0, 1.0)


def batch_indices(size: int, batch_size: int, rng: np.random.Generator) -> Iterator[np.ndarray]:
    """Endless batches of sample indices: a fresh permutation each epoch, no sample twice in one."""
    batch_size = min(batch_size, size)
    order = np.zeros(0, dtype=np.intp)
    while True:
        while len(order) < batch_size:
            order = np.concatenate([order, rng.permutation(size)])
        yield order[:batch_size]
        order = order[batch_size:]


def train(
    network: nn.Module,
    batch_loss: Callable[[Batch], Tensor],
    dataset: Dataset,
    config: TrainConfig,
    progress: bool = True,
    description: str = "train",
    parameters: Iterable[nn.Parameter] | None = None,
) -> TrainReport:
    """Trains ``network``'s parameters to lower ``batch_loss`` on ``dataset``; leaves it in eval.

    ``parameters``, when given, are the only ones the optimiser moves (a later training phase
    on a frozen encoder); by default every parameter of ``network``.

    Raises:
        TrainingError: The loss became NaN or infinite (the message names the step).

    """
    if len(dataset) == 0:
        raise InvalidInputError("dataset", "0 samples", "at least one sample")
    device = torch.device(config.device)
    threads = config.threads or default_threads()
    previous_threads = torch.get_num_threads()
    torch.set_num_threads(threads)
    rng = np.random.default_rng(config.seed)
    generator = torch.Generator().manual_seed(config.seed)
    network.to(device).train()
    trained = list(network.parameters() if parameters is None else parameters)
    if not trained:
        raise InvalidInputError("parameters", "none", "at least one parameter to train")
    optimiser = torch.optim.Adam(trained, lr=config.learning_rate,
                                 weight_decay=config.weight_decay)
    schedule = torch.optim.lr_scheduler.LambdaLR(optimiser, lambda step: 1.0 if
                                                 config.lr_schedule == "constant" else
                                                 0.5 * (1 + math.cos(math.pi * step /
                                                                     config.steps)))
    conditions = torch.from_numpy(dataset.conditions).to(device)  # (N, C)
    jitter = config.augment and config.sentence_noise > 0 and \
        dataset.metadata.condition_kind is ConditionKind.TEXT
    labels = torch.from_numpy(dataset.labels).to(device)  # (N, q, D)
    type_indices = torch.from_numpy(dataset.target_type_indices()).to(device)  # (N, q)
    present = torch.from_numpy(dataset.target_present()).to(device)  # (N, q)
    depths = None if dataset.depths_m is None else torch.from_numpy(dataset.depths_m)  # (N, H, W)
    losses: list[tuple[int, float]] = []
    window: list[float] = []
    started = time.perf_counter()
    bar = tqdm(range(1, config.steps + 1), desc=description, disable=not progress, unit="step")
    try:
        batches = batch_indices(len(dataset), config.batch_size, rng)
        for step in bar:
            index = next(batches)
            images = images_to_tensor(dataset.images[index], device)  # (B, 3, H, W)
            if config.augment:
                images = photometric_augment(images, generator, config.hue_jitter)
            asked = conditions[index]  # (B, C)
            if jitter:
                noise = torch.randn(asked.shape, generator=generator).to(device)
                asked = nn.functional.normalize(asked + config.sentence_noise * noise, dim=1)
            loss = batch_loss(Batch(images, asked, labels[index], type_indices[index],
                                    present[index],
                                    None if depths is None else depths[index].to(device)))
            if not torch.isfinite(loss):
                raise TrainingError(f"{description}: the loss became {loss.item()} at step "
                                    f"{step}; try a lower learning_rate (now "
                                    f"{config.learning_rate})")
            optimiser.zero_grad(set_to_none=True)
            loss.backward()
            optimiser.step()
            schedule.step()
            window.append(loss.item())
            if step % config.log_every == 0 or step == config.steps:
                losses.append((step, float(np.mean(window))))
                bar.set_postfix(loss=f"{losses[-1][1]:.4g}")
                window = []
    finally:
        network.eval()
        torch.set_num_threads(previous_threads)
    return TrainReport(config.steps, len(dataset), losses[-1][1], tuple(losses),
                       time.perf_counter() - started, threads, config)
