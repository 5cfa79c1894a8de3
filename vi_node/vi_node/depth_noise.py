"""The Kinect v1's depth noise at a depth (beyond paper section 2.2: the paper's tolerances are fixed).

Axial noise sigma_z = 0.0012 + 0.0019 (z - 0.4)^2 m (Nguyen et al. 2012) and the disparity step,
2.85e-3 z^2 m (Khoshelham and Elberink 2012: 1/z = -2.85e-3 d + 3.0 with integer disparity d). At
1 m that is 1.9 mm and 2.9 mm; at 3 m, 14 mm and 26 mm, so a tile's motion of 2 cm, plain at a
metre, is within one step there.
"""

from __future__ import annotations

from typing import TypeVar

import numpy as np
from numpy.typing import NDArray

Depth = TypeVar("Depth", float, NDArray[np.float32], NDArray[np.float64])


def axial_sigma(depth: Depth) -> Depth:
    """Standard deviation (m) of a depth measured at `depth` (m) along the optical axis."""
    return 0.0012 + 0.0019 * (depth - 0.4) ** 2  # type: ignore[return-value]


def disparity_step(depth: Depth) -> Depth:
    """The depth (m) between two successive disparities at `depth` (m)."""
    return 2.85e-3 * depth**2  # type: ignore[return-value]


def resolved_motion(depth: Depth) -> Depth:
    """The smallest motion (m) of a surface at `depth` (m) that stands out of the noise: one sigma
    plus half a disparity step (1.2 cm at 2 m, 2.7 cm at 3 m)."""
    return axial_sigma(depth) + 0.5 * disparity_step(depth)  # type: ignore[return-value]
