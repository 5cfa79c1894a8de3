"""A laser scan as the drivers and the tile localization see it (the content of
sensor_msgs/LaserScan, without ROS)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray


@dataclass(frozen=True)
class LaserScanData:
    stamp: float  # s; time.monotonic() in the driver, the message stamp elsewhere
    angle_min: float  # rad, angle of the first range, counter-clockwise from the front axis
    angle_increment: float  # rad between consecutive ranges
    ranges: NDArray[np.float64]  # m; NaN: no valid measurement, +inf: beyond range_max
    range_min: float  # m
    range_max: float  # m
    time_increment: float = 0.0  # s between measurements
    scan_time: float = 0.0  # s between scans

    @property
    def angles(self) -> NDArray[np.float64]:
        return self.angle_min + self.angle_increment * np.arange(len(self.ranges))

    @property
    def angle_max(self) -> float:
        return self.angle_min + self.angle_increment * (len(self.ranges) - 1)

    def valid(self) -> NDArray[np.bool_]:
        r = self.ranges
        return np.isfinite(r) & (r >= self.range_min) & (r <= self.range_max)

    def points(self) -> NDArray[np.float64]:
        """(N, 2) points of the valid ranges in the laser frame (x forward, y left)."""
        keep = self.valid()
        r, a = self.ranges[keep], self.angles[keep]
        return np.column_stack([r * np.cos(a), r * np.sin(a)])
