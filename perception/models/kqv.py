"""The paper's Key-Query-Value visual attention model, ``kqv``, as a :class:`PerceptionModel`.

:class:`KqvModel` trains its :class:`~perception.models.kqv_net.KqvNet` (temperature warm-up,
several starts, then the type head) and predicts with the learned Queries or with Queries given
from outside. Its settings are :class:`KqvConfig`; where they depart from the paper and why:
``docs/decisions/kqv.md``.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import replace
from typing import Any, cast

import numpy as np
import torch
from torch import Tensor, nn

from perception.camera import Calibrations
from perception.interface import Condition, InvalidInputError, ModelInput, Prediction
from perception.language.sentence_reading import TokenReader, read_sentences
from perception.learning.data import Dataset
from perception.learning.evaluate import evaluate
from perception.learning.learnable import ModelSpec
from perception.learning.mirror import Mirror
from perception.learning.torch_pieces import (
    LabelScaler,
    images_to_tensor,
    normalised_to_pixels,
    unit,
)
from perception.learning.train import Batch, TrainConfig, TrainReport, train
from perception.learning.validation import split_scenes
from perception.models.kqv_config import INFERENCE_FIELDS, KqvConfig
from perception.models.kqv_net import KqvNet
from perception.models.kqv_samples import mirror_for, named_dataset, sentence_reader
from perception.models.repaint import Repaint
from perception.models.rise import checked_depths
from perception.models.torch_model import Phase, TorchModel, present_mean


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

    def __init__(self, spec: ModelSpec, config: KqvConfig | None = None,
                 scaler: LabelScaler | None = None) -> None:
        super().__init__(spec, config, scaler)
        if self.reads_depth:  # a trial gives it the frame's depth too
            self.inputs = self.inputs | {ModelInput.DEPTH}

    @property
    def reads_depth(self) -> bool:
        """Whether the network reads each image's depth: its input, or the range readout's."""
        return self.config.depth_input or self.network.readout == "range"

    def build_network(self) -> KqvNet:
        """The Key, Value, Query and head networks for this spec."""
        network = KqvNet(self.spec, self.config)
        network.scaler = self.scaler
        if network.prototypes is not None and self._prototypes is not None:
            network.prototypes.copy_(self._prototypes)
        if network.reader is not None and self._reader is not None:  # every start reads alike
            network.reader.load_state_dict(self._reader.state_dict())
        return network

    @classmethod
    def hyperparameters_from(cls, saved: dict[str, Any], tensors: frozenset[str] = frozenset()
                             ) -> dict[str, Any]:
        """The saved hyper-parameters, with older checkpoints' settings made explicit.

        A checkpoint from before sentence prototypes reads the sentence embedding itself, as
        it was trained to. One whose ``"auto"`` Query form kept Base Queries beside the
        condition's (a sentence naming a side, before it took its one-hot twin's form) keeps
        them.
        """
        values = {"sentence_reading": "embedding"} | saved
        if values.get("query_mode", "auto") == "auto" and "base_queries" in tensors and \
                "query_mlp.0.weight" in tensors:
            values["query_mode"] = "conditioned+base"
        return values

    @classmethod
    def tensors_from(cls, saved: dict[str, Tensor], expected: Mapping[str, Tensor]
                     ) -> dict[str, Tensor]:
        """A token reader saved before it kept the words it saw reads every word, as trained."""
        if "reader.seen" in expected and "reader.seen" not in saved:
            return saved | {"reader.seen": torch.ones_like(expected["reader.seen"])}
        return saved

    _prototypes: Tensor | None = None  # (k, C) a sentence task's prototypes, set on first fit
    _reader: TokenReader | None = None  # what a sentence names, from its words; first fit
    _steps_taken = 0  # training steps of the current fit, for the temperature warm-up
    _mirror: Mirror | None = None  # mirrors training samples (KqvConfig.mirror)
    _repaint: Repaint | None = None  # repaints what the Value map sees (KqvConfig.repaint)

    def fit(self, dataset: Dataset, config: TrainConfig | None = None,
            progress: bool = True) -> TrainReport:
        """Trains as :meth:`TorchModel.fit` does, warming the temperature up first.

        The softmax temperature starts at :attr:`KqvConfig.warmup_temperature` and falls to
        :attr:`KqvConfig.temperature` over :attr:`KqvConfig.warmup_steps`; afterwards, and
        whatever happens during training, the network is left at ``temperature``. On the first
        fit, :attr:`KqvConfig.starts` initialisations train :attr:`KqvConfig.start_steps` steps
        each and the best goes on; ``config.steps`` counts its steps, and the report's wall
        time includes the dropped starts'.

        With a type head, :attr:`KqvConfig.type_steps` more steps then train it alone, but
        never more than ``config.steps``: a short training (a smoke run of a few steps) is
        short in both phases, and one of ``type_steps`` steps or more trains the head as it
        always did. The report names its phases (``"starts"`` where several were tried,
        ``"targets"``, ``"object types"``), each with its wall time, and its ``final_loss``
        stays the targets'. A dataset that names no target's type trains no type phase.
        """
        config = config or TrainConfig()
        if self.config.depth_input and dataset.depths_m is None:  # paper-sim's; older ones'
            raise InvalidInputError("depth_input", True, "false for a dataset without depth "
                                    "images")
        if self.network.readout == "range" and dataset.depths_m is None:
            if self.config.readout != "auto-range" or self.scaler is not None:
                raise InvalidInputError("readout", self.config.readout, "'ray', 'mlp' or 'auto' "
                                        "for a dataset without depth images")
            # The default reads the range where the frame measures it: without depth images,
            # the ray readout, recorded as such in the checkpoint.
            self.config = replace(self.config, readout="ray")
            self.network = self.build_network()
            self.inputs = self.inputs - {ModelInput.DEPTH}  # depth_input is refused above
        if self.config.repaint and dataset.depths_m is None:  # objects are found by depth
            raise InvalidInputError("repaint", self.config.repaint, "0 for a dataset without "
                                    "depth images")
        self._repaint = Repaint(self.config.repaint, config.seed) if self.config.repaint \
            else None
        if self.config.hue_jitter:  # the model's setting reaches the training loop
            config = replace(config, hue_jitter=self.config.hue_jitter)
        fresh = self.scaler is None  # a first fit may try several starts; a later one not
        if fresh:
            self.spec.check_dataset(dataset)
            self.scaler = LabelScaler.fit(dataset.labels[..., :3])
            self.network.scaler = self.scaler
            if self.network.prototypes is not None:  # what each target's sentences sound like
                self._prototypes = torch.from_numpy(dataset.condition_prototypes())
                self.network.prototypes.copy_(self._prototypes)
            if self.network.reader is not None:  # which words name which target
                self._reader = sentence_reader(dataset, self.spec, self.config.seed)
                self.network.reader.load_state_dict(self._reader.state_dict())
        self._mirror = mirror_for(self.spec, self.config.mirror, dataset, self.network.prototypes,
                                  config.seed)
        named = named_dataset(dataset, self.network.prototypes)
        try:
            pose = self._fit_pose(dataset, named, fresh, config, progress)
        finally:
            self.network.temperature = self.config.temperature
        if self.network.type_head is None or not (dataset.target_type_indices() >= 0).any():
            return pose
        types = train(self.network, self.type_loss, named,
                      replace(config, steps=min(self.config.type_steps, config.steps)),
                      progress,
                      description=f"{self.name} {self.spec.task} [object types]",
                      parameters=self.network.type_head.parameters())
        chained = TrainReport.chain([pose, types], ("targets", "object types"))
        self.report = replace(chained, final_loss=pose.final_loss, config=config)
        return self.report

    def _fit_pose(self, dataset: Dataset, named: Dataset, fresh: bool, config: TrainConfig,
                  progress: bool) -> TrainReport:
        """The pose training of :meth:`fit`: on a ``fresh`` model the starts, then the rest.

        It trains on ``named`` (:meth:`_named` of ``dataset``); the starts are compared on
        scenes of ``dataset`` held out with their own sentences.
        """
        if not fresh or self.config.starts == 1 or config.steps <= self.config.start_steps:
            self._steps_taken = 0
            return super().fit(named, config, progress)
        start = self._best_start(dataset, config, progress)
        rest = super().fit(named, replace(config, steps=config.steps - start.steps),
                           progress)  # the warm-up goes on from the step the start reached
        self.report = replace(TrainReport.chain([start, rest], ("starts", "targets")),
                              config=config)
        return self.report

    def condition_rows(self, conditions: Sequence[Condition], rows: np.ndarray) -> np.ndarray:
        """Each sentence's row as the network reads it, under the ``"tokens"`` reading.

        The unit prototype of the target the reader reads the sentence as naming (what that
        target's training sentences become in :meth:`_named`); other readings' rows as given.
        """
        reader, prototypes = self.network.reader, self.network.prototypes
        if reader is None or prototypes is None:
            return rows
        read = read_sentences(reader, [c.value or "" for c in conditions])
        return unit(prototypes, dim=-1).numpy()[read].astype(np.float32)

    def phases(self) -> list[Phase]:
        """One phase: the target loss on every parameter but the type head's (see :meth:`fit`)."""
        return [Phase("targets", self.batch_loss, self._pose_parameters())]

    def _pose_parameters(self) -> list[nn.Parameter]:
        """The network's parameters that the pose training moves: all but the type head's."""
        apart = [m for m in (self.network.type_head, self.network.reader) if m is not None]
        skipped = {id(p) for module in apart for p in module.parameters()}
        return [p for p in self.network.parameters() if id(p) not in skipped]

    def _best_start(self, dataset: Dataset, config: TrainConfig, progress: bool
                    ) -> TrainReport:
        """Trains :attr:`KqvConfig.starts` fresh networks briefly and keeps the best one.

        The starts train on the scenes :attr:`KqvConfig.start_holdout` leaves and are compared
        on the held-out ones as the trials judge a pick: by the grasp judge's expected success
        (:mod:`perception.learning.judged_errors`; rotation and each object's tolerance
        included), then by mean position error (all a position label has), then by training
        loss (where nothing is held out). The held-out scenes keep their own sentences
        (:meth:`_named` is for training only).
        Returns the kept start's report, its wall time that of every start and comparison.
        """
        started = time.perf_counter()
        short = replace(config, steps=self.config.start_steps,
                        batch_size=self.config.start_batch_size or config.batch_size)
        kept, held = split_scenes(dataset, self.config.start_holdout, config.seed)
        kept = named_dataset(kept, self.network.prototypes)
        tried: list[tuple[float, float, float, int, KqvNet, TrainReport]] = []
        for number in range(self.config.starts):
            seed = self.config.seed if number == 0 else int(
                np.random.SeedSequence([self.config.seed, number]).generate_state(1)[0] >> 1)
            self.network = cast(KqvNet, self.seeded_network(seed))
            self._steps_taken = 0
            report = train(self.network, self.batch_loss, kept, short, progress,
                           description=f"{self.name} {self.spec.task} [start {number + 1}/"
                           f"{self.config.starts}]", parameters=self._pose_parameters())
            self.network.temperature = self.config.temperature
            scored = None if held is None else evaluate(self, held)
            judged = 0.0 if scored is None or scored.judged is None else \
                -scored.judged.all.expected_success_rate
            held_cm = 0.0 if scored is None else scored.mean_position_error_cm
            tried.append((judged, held_cm, report.final_loss, number, self.network, report))
        *_, self.network, kept_report = min(tried, key=lambda t: t[:4])
        self._steps_taken = self.config.start_steps
        return replace(kept_report, wall_time_s=time.perf_counter() - started)

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
        self.network.focus_now = c.focus_training and done >= 1.0  # as inference reads
        self._steps_taken += 1
        if self._mirror is not None:
            batch = self._mirror(batch)
        out = self.network(batch.images, batch.conditions, depths_m=batch.depths_m,
                           value_images=self._repainted(batch))
        loss = self.target_loss(out, batch.labels, batch.present)
        camera = self.network.seen
        if camera is not None and c.point_loss_weight > 0 and out.points is not None:
            seen = camera.project(batch.labels[..., :3])  # (B, q, 2)
            loss = loss + c.point_loss_weight * present_mean(
                (out.points - seen).square().sum(-1), batch.present)
        return loss

    def _repainted(self, batch: Batch) -> Tensor | None:
        """The batch's images as the Value map sees them in training (None: as the Key does)."""
        if self._repaint is None or batch.depths_m is None:
            return None
        return self._repaint(batch.images, batch.depths_m)

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
            features = self.network.attend(batch.images, queries, batch.depths_m,
                                           self._repainted(batch)).features  # (B, q, Cv)
        logits = head(features)  # (B, q, T)
        known = indices >= 0  # (B, q)
        if not known.any():
            return logits.sum() * 0.0  # no type known in this batch: nothing to learn
        return nn.functional.cross_entropy(logits[known], indices[known])  # (n, T) vs (n,)

    @torch.no_grad()
    def predict_batch(self, images: np.ndarray, conditions: np.ndarray,
                      depths_m: np.ndarray | None = None, queries: np.ndarray | None = None,
                      *, cameras: Calibrations = None) -> list[Prediction]:
        """Predictions for uint8 images (B, H, W, 3) and conditions (B, C).

        ``depths_m`` (B, H, W) [m]: the images' depth, which a model with
        :attr:`KqvConfig.depth_input` needs (others ignore it). ``queries`` (B, q, Ck + 2),
        when given, replaces the learned Queries (top-down control from outside; see
        :meth:`queries` for the learned ones). ``cameras``: each image's calibration, which
        the ray readout reads positions through (None: the camera of the training images).
        """
        self.check_batch(images, conditions)
        given = None if queries is None else self._check_queries(queries, len(images))
        out = self.network(images_to_tensor(images), torch.as_tensor(conditions).float(), given,
                           self._depths(depths_m, len(images)), cameras=cameras)
        return self.to_predictions(out, conditions)

    def _depths(self, depths_m: np.ndarray | None, batch: int, needed: bool | None = None
                ) -> Tensor | None:
        """The depth images a depth-reading network is given, checked; None for the others.

        ``needed``: whether this call reads them (attention alone reads no range); None: as
        :attr:`reads_depth` says.
        """
        shape = (batch, self.spec.image_height_px, self.spec.image_width_px)
        needed = self.reads_depth if needed is None else needed
        return checked_depths(depths_m, shape) if needed else None

    def read_with(self, **settings: Any) -> KqvModel:
        """The same trained weights read under other inference settings (:data:`INFERENCE_FIELDS`).

        The focus acts at inference only, so a checkpoint is scored with and without it (the
        ablation's ``minus-focus`` row, the distractor checks) without training again.

        Raises:
            InvalidInputError: A setting that training depends on, or a value the config
                refuses.

        """
        for name in settings:
            if name not in INFERENCE_FIELDS:
                raise InvalidInputError(name, settings[name], "a training setting; read_with "
                                        f"changes only {', '.join(sorted(INFERENCE_FIELDS))}")
        other = type(self)(self.spec, replace(self.config, **settings), self.scaler)
        other._prototypes, other._reader = self._prototypes, self._reader
        other.report = self.report
        other.provenance = dict(self.provenance)
        other.network.load_state_dict(self.network.state_dict())
        return other

    @torch.no_grad()
    def queries(self, conditions: np.ndarray) -> np.ndarray:
        """The learned Query vectors (B, q, Ck + 2) for one-hot conditions (B, C)."""
        return self.network.queries(torch.as_tensor(conditions).float()).numpy()

    @torch.no_grad()
    def read_sentences(self, embeddings: np.ndarray) -> np.ndarray | None:
        """How sentence embeddings (B, C) read as the named targets: (B, k) weights, or None.

        The weights :attr:`KqvConfig.sentence_reading` reads the Query from (by prototypes),
        in ``spec.condition_choices`` order, each row summing to 1; None for a model that reads
        no sentence or reads the embedding itself. What the model took a sentence to mean.
        """
        if self.network.prototypes is None:
            return None
        rows = torch.from_numpy(np.array(embeddings, np.float32))  # a copy: theirs may be frozen
        return self.network.sentence_weights(rows).numpy()

    @torch.no_grad()
    def attend(self, images: np.ndarray, queries: np.ndarray,
               depths_m: np.ndarray | None = None) -> dict[str, np.ndarray]:
        """Attention of uint8 images (B, H, W, 3) under any Queries (B, q', Ck + 2).

        Returns ``points_px`` (B, q', 2) (u right, v down), ``heatmaps`` (B, q', h, w) and
        ``features`` (B, q', Cv): where each Query looks and what it sees there. ``depths_m``
        as :meth:`predict_batch` takes it.
        """
        self.check_batch(images, np.zeros((len(images), self.spec.condition_size)))
        attention = self.network.attend(images_to_tensor(images),
                                        self._check_queries(queries, len(images), any_q=True),
                                        self._depths(depths_m, len(images),
                                                     self.config.depth_input))
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
