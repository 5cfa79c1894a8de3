"""Tile localization from the laser (paper section 3.1) on synthetic scans with range noise: every
tile type of the paper's structure is found within 1 cm, wrong or absent tiles are not."""

from __future__ import annotations

import math
import zlib

import numpy as np
import pytest
from conftest import STRUCTURES

from hardware_drivers.emulators.urg_emulator import ray_cast
from hardware_drivers.laser_scan import LaserScanData
from hardware_drivers.planar_pose import Pose2D
from hardware_drivers.scip import URG_04LX
from hardware_drivers.tile_localization import (
    LocalizationParams,
    explain_no_tile,
    find_tile,
    footprint_of,
    rotational_symmetry,
    segment_scan,
)
from tiling_assembly.structure_file import load_structure

TYPES = load_structure(STRUCTURES / "paper_14.yaml").tile_types
ANGLES = np.array([URG_04LX.step_angle(s) for s in range(URG_04LX.amin, URG_04LX.amax + 1)])
WALL = np.array([[0.9, -2.0, 0.9, 2.0]])  # a wall behind the tiles


def scan_of(tiles: list[tuple[np.ndarray, Pose2D]], noise: float, rng: np.random.Generator) -> LaserScanData:
    """What the URG-04LX at the origin measures: ray cast, Gaussian noise, 1 mm steps, DMIN/DMAX."""
    segments = [WALL]
    for polygon, pose in tiles:
        corners = pose.transform_points(polygon)
        segments.append(np.hstack([corners, np.roll(corners, -1, axis=0)]))
    ranges = ray_cast(Pose2D(), ANGLES, np.vstack(segments)) + rng.normal(0.0, noise, len(ANGLES))
    ranges = np.round(ranges, 3)
    ranges[(ranges < 0.02) | (ranges > 5.6)] = np.nan
    return LaserScanData(0.0, float(ANGLES[0]), URG_04LX.angle_increment, ranges, 0.02, 5.6)


def symmetric_yaw_error(a: float, b: float, symmetry: int) -> float:
    period = 2 * math.pi / symmetry
    return abs((a - b + period / 2) % period - period / 2)


@pytest.mark.parametrize("type_name", sorted(TYPES))
def test_every_tile_type_is_found_within_one_centimetre(type_name: str) -> None:
    rng = np.random.default_rng(zlib.crc32(type_name.encode()))
    polygon = footprint_of(TYPES[type_name])
    symmetry = rotational_symmetry(polygon)
    for _ in range(6):
        # where the M3 robot sees a tile at its cache: 0.2-0.35 m ahead of the laser
        truth = Pose2D(rng.uniform(0.18, 0.35), rng.uniform(-0.12, 0.12), rng.uniform(-math.pi, math.pi))
        detection = find_tile(scan_of([(polygon, truth)], 0.003, rng), polygon)
        assert detection is not None, f"{type_name} at {truth} not found"
        assert math.hypot(detection.pose.x - truth.x, detection.pose.y - truth.y) < 0.01, (truth, detection)
        assert symmetric_yaw_error(detection.pose.yaw, truth.yaw, symmetry) < math.radians(12)
        assert detection.rms < 0.006 and 0.0 < detection.quality <= 1.0


def test_symmetry_of_the_paper_tiles() -> None:
    orders = {name: rotational_symmetry(footprint_of(t)) for name, t in TYPES.items()}
    assert orders == {"long_rectangle": 2, "trapezoid": 1, "octagon": 8, "square": 4, "triangle": 3}
    rectangle = footprint_of(TYPES["long_rectangle"])
    assert rectangle.shape == (4, 2) and np.ptp(rectangle[:, 0]) == pytest.approx(0.17)


def test_yaw_is_reported_within_the_symmetry_period() -> None:
    rng = np.random.default_rng(3)
    polygon = footprint_of(TYPES["long_rectangle"])
    detection = find_tile(scan_of([(polygon, Pose2D(0.3, 0.0, 2.9))], 0.002, rng), polygon)
    assert detection is not None
    assert -math.pi / 2 <= detection.pose.yaw < math.pi / 2
    assert symmetric_yaw_error(detection.pose.yaw, 2.9, 2) < math.radians(5)


def test_no_tile_gives_none_and_a_reason() -> None:
    rng = np.random.default_rng(4)
    polygon = footprint_of(TYPES["square"])
    scan = scan_of([], 0.003, rng)
    assert find_tile(scan, polygon) is None
    assert "no cluster of tile size" in explain_no_tile(scan, polygon)


def test_a_tile_of_another_type_is_not_taken_for_the_one_looked_for() -> None:
    rng = np.random.default_rng(5)
    square, rectangle = footprint_of(TYPES["square"]), footprint_of(TYPES["long_rectangle"])
    assert find_tile(scan_of([(square, Pose2D(0.3, 0.0, 0.5))], 0.003, rng), rectangle) is None
    assert find_tile(scan_of([(rectangle, Pose2D(0.3, 0.0, 0.5))], 0.003, rng), square) is None


def test_the_region_of_interest_selects_between_two_tiles() -> None:
    rng = np.random.default_rng(6)
    octagon = footprint_of(TYPES["octagon"])
    scan = scan_of([(octagon, Pose2D(0.3, 0.2, 0.1)), (octagon, Pose2D(0.35, -0.2, 0.3))], 0.003, rng)
    detection = find_tile(scan, octagon, region=(0.35, -0.2, 0.1))
    assert detection is not None and detection.pose.distance_to(Pose2D(0.35, -0.2)) < 0.01


def test_segmentation_separates_a_tile_from_the_wall_behind() -> None:
    rng = np.random.default_rng(7)
    polygon = footprint_of(TYPES["trapezoid"])
    scan = scan_of([(polygon, Pose2D(0.3, 0.0, 0.0))], 0.003, rng)
    clusters = segment_scan(scan, LocalizationParams())
    near = [c for c in clusters if np.nanmax(scan.ranges[c]) < 0.5]
    assert len(near) == 1
