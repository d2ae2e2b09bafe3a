"""TCP poses the planner tests aim at: imported by tests in any folder (``pythonpath = tests``).

Not in conftest.py: a second conftest.py (tests/examples/) makes ``from conftest import``
ambiguous, so shared helpers live in modules of their own.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin


def top_down(x: float, y: float, z: float, yaw: float = np.pi / 2) -> pin.SE3:
    """A TCP pose pointing straight down, fingers closing along the yawed x axis."""
    down = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])
    return pin.SE3(pin.utils.rotate("z", yaw) @ down, np.array([x, y, z]))
