"""Kinematics of any URDF robot on Pinocchio: joint bookkeeping by name, FK and Jacobians."""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path

import numpy as np
import pinocchio as pin

from control.errors import InvalidInputError


class RobotModel:
    """A Pinocchio model with its joints addressed by name.

    Only one-degree-of-freedom joints (revolute, prismatic) are supported, so every joint has one
    entry in the configuration vector ``q`` and the order of ``joint_names`` is the order of
    ``q``. That order is Pinocchio's tree traversal, not the URDF's: look joints up by name.

    Args:
        model: The Pinocchio model.
        srdf_path: Optional SRDF whose ``group_state`` entries become ``reference_configurations``.

    """

    def __init__(self, model: pin.Model, srdf_path: str | Path | None = None) -> None:
        if model.nq != model.nv:
            raise InvalidInputError(
                "model", model.name, "a model whose joints each have one degree of freedom"
            )
        self.model = model
        self.data = model.createData()
        self.joint_names: tuple[str, ...] = tuple(model.names[i] for i in range(1, model.njoints))
        self._index = {name: model.joints[i].idx_q for i, name in enumerate(model.names) if i > 0}
        self.lower_rad = np.array(model.lowerPositionLimit, dtype=float)  # (nq,)
        self.upper_rad = np.array(model.upperPositionLimit, dtype=float)  # (nq,)
        self.max_velocity = np.array(model.velocityLimit, dtype=float)  # (nq,)
        self.reference_configurations: dict[str, np.ndarray] = {}
        if srdf_path is not None:
            pin.loadReferenceConfigurations(model, str(srdf_path), False)
            for entry in model.referenceConfigurations:  # a C++ map: entries, not keys
                self.reference_configurations[entry.key()] = np.array(entry.data(), dtype=float)

    @classmethod
    def from_urdf(
        cls, urdf_path: str | Path, srdf_path: str | Path | None = None
    ) -> RobotModel:
        """Loads a fixed-base robot from a URDF file (and optionally its SRDF)."""
        path = Path(urdf_path)
        if not path.is_file():
            raise InvalidInputError("urdf_path", str(path), "an existing URDF file")
        return cls(pin.buildModelFromUrdf(str(path)), srdf_path)

    @property
    def nq(self) -> int:
        """Number of configuration entries."""
        return int(self.model.nq)

    def joint_index(self, name: str) -> int:
        """Index of a joint in ``q``."""
        try:
            return self._index[name]
        except KeyError:
            raise InvalidInputError(
                "joint", name, f"one of the model's joints: {', '.join(self.joint_names)}"
            ) from None

    def joint_indices(self, names: Iterable[str]) -> np.ndarray:
        """Indices of several joints in ``q``, in the given order."""
        return np.array([self.joint_index(n) for n in names], dtype=int)

    def frame_id(self, name: str) -> int:
        """Pinocchio id of a frame, with a clear error for an unknown name."""
        if not self.model.existFrame(name):
            frames = sorted({f.name for f in self.model.frames})
            allowed = f"one of the model's frames: {', '.join(frames)}"
            raise InvalidInputError("frame", name, allowed)
        return int(self.model.getFrameId(name))

    def q_from_dict(
        self, values: Mapping[str, float], default: np.ndarray | None = None
    ) -> np.ndarray:
        """A configuration vector from joint values keyed by name.

        Joints not in ``values`` take their entry of ``default`` (the neutral configuration when
        ``default`` is None). Unknown names are an error, never ignored.
        """
        q = pin.neutral(self.model) if default is None else np.array(default, dtype=float)
        for name, value in values.items():
            q[self.joint_index(name)] = float(value)
        return q

    def dict_from_q(self, q: np.ndarray, names: Sequence[str] | None = None) -> dict[str, float]:
        """Joint values keyed by name, for all joints or the ``names`` given."""
        self.check_shape(q)
        chosen = self.joint_names if names is None else names
        return {name: float(q[self.joint_index(name)]) for name in chosen}

    def check_shape(self, q: np.ndarray) -> None:
        """Raises a clear error unless ``q`` is a configuration vector of this model."""
        if np.shape(q) != (self.nq,):
            raise InvalidInputError("q", f"array of shape {np.shape(q)}", f"shape ({self.nq},)")

    def within_limits(self, q: np.ndarray, tolerance: float = 1e-9) -> bool:
        """Whether every joint is within its position limits (plus ``tolerance``)."""
        return bool(
            np.all(q >= self.lower_rad - tolerance) and np.all(q <= self.upper_rad + tolerance)
        )

    def clip_to_limits(
        self, q: np.ndarray, field: str = "q", tolerance: float = 1e-3
    ) -> np.ndarray:
        """``q`` clipped into the position limits, for a measured configuration.

        A simulated or real joint sits a hair past its limit now and then; up to ``tolerance``
        [rad] or [m] past it is clipped, further is an error naming the joint and its range.
        """
        self.check_shape(q)
        outside = (q < self.lower_rad - tolerance) | (q > self.upper_rad + tolerance)
        if np.any(outside):
            i = int(np.argmax(outside))
            name = self.joint_names[i]
            raise InvalidInputError(f"{field}[{name}]", float(q[i]),
                                    f"within [{self.lower_rad[i]:.6g}, {self.upper_rad[i]:.6g}]")
        return np.clip(q, self.lower_rad, self.upper_rad)

    def random_configuration(self, rng: np.random.Generator) -> np.ndarray:
        """A configuration drawn uniformly within the position limits."""
        return rng.uniform(self.lower_rad, self.upper_rad)

    def frame_pose(self, q: np.ndarray, frame: str) -> pin.SE3:
        """Pose of ``frame`` in the world (root) frame at configuration ``q``: ``T_world_frame``."""
        self.check_shape(q)
        frame_id = self.frame_id(frame)
        pin.forwardKinematics(self.model, self.data, q)
        return pin.updateFramePlacement(self.model, self.data, frame_id).copy()

    def frame_jacobian(
        self,
        q: np.ndarray,
        frame: str,
        reference: pin.ReferenceFrame = pin.LOCAL_WORLD_ALIGNED,
    ) -> np.ndarray:
        """The (6, nq) Jacobian of ``frame``'s twist (linear first), in ``reference`` axes."""
        self.check_shape(q)
        return np.array(
            pin.computeFrameJacobian(self.model, self.data, q, self.frame_id(frame), reference)
        )
