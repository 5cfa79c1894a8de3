"""Other robots in the Kinect's view: which pixels show them (beyond paper section 2.2.1, where
"points of the original raw data which were unlikely to support the structure were removed").

While the team builds, assembly robots stand beside the structure, a few centimetres from its
tiles, inside the box where the alignment looks for candidate points. Their flat sides pull ICP
and the coarse search off, and they are not part of S_a. Two ways to find them, both giving a
pixel mask that the alignment and the classification leave out:

- `tall_things`: anything standing higher than the structure (robots, people, bins) is not a tile.
  After the floor correction the heights are right even when x, y and yaw are not yet, and the
  sides of a robot rise straight from its footprint: so the footprint of the points above the
  structure's top, widened a little, holds every point of such a thing at any height.
- `inside_robots`: the overhead cameras localize every robot (an `OverheadPose` each, from their
  `overhead_pose` topics); once the scan is aligned, the points inside a robot's box, grown by the
  localization error, are that robot's. This catches robots whose tops the camera does not see.

`RobotBoxes` also lets the choice of the next viewpoint see the robots: what they hide, and where
the VI robot cannot stand.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage
from scipy.spatial import cKDTree

from vi_node.camera_model import PinholeCamera
from vi_node.pose_prior import OverheadPose

Array = NDArray[np.float64]
Mask = NDArray[np.bool_]


@dataclass(frozen=True)
class RobotMaskSettings:
    size: tuple[float, float, float] = (0.33, 0.33, 0.35)  # m, a robot's box: x, y along its base, height
    position_error: float = 0.05  # m, overhead localization error of a robot, up to
    yaw_error: float = 0.175  # rad (10 deg), ... and of its heading
    tall_margin: float = 0.03  # m above the structure's top: higher points belong to something else
    tall_widen: float = 0.01  # m around the footprint of tall things (lateral noise, sparse rows)
    cell: float = 0.01  # m, grid of the footprint


def tall_things(
    cloud: NDArray[np.float32],
    camera: PinholeCamera,
    pose: Array,
    low: Array,
    high: Array,
    reach: float,
    floor_clearance: float,
    settings: RobotMaskSettings,
) -> Mask:
    """Pixels (H, W) around the box [low, high] (within `reach` in x and y, up to its top) of things
    that stand higher than `high[2]` + margin: everything above the floor inside the widened
    footprint of their higher points.

    `pose`: the optical frame in the map, right in height, roll and pitch (after the floor fit).
    """
    mask = np.zeros(cloud.shape[:2], dtype=bool)
    area_low = np.array([low[0] - reach, low[1] - reach, floor_clearance])
    area_high = np.array([high[0] + reach, high[1] + reach, 2.5])
    shape = np.ceil((area_high[:2] - area_low[:2]) / settings.cell).astype(int) + 1
    # the footprint: every other pixel is plenty for 1 cm cells of things 30 cm wide
    rows, cols = camera.box_roi(pose, area_low, area_high)
    sparse = cloud[rows.start : rows.stop : 2, cols.start : cols.stop : 2]
    points = _standing(sparse, pose, high[2] + settings.tall_margin)
    if len(points) == 0:
        return mask
    grid = np.zeros(shape, dtype=bool)
    cell, inside = _cells(points, pose, area_low, settings.cell, shape)
    grid[cell[inside, 0], cell[inside, 1]] = True
    grid = ndimage.binary_dilation(grid, iterations=max(1, round(settings.tall_widen / settings.cell)))
    # the mask: every pixel that can see the box the alignment takes its points from
    box_high = np.array([high[0] + reach, high[1] + reach, high[2] + settings.tall_margin])
    rows, cols = camera.box_roi(pose, area_low, box_high)
    window = cloud[rows, cols]
    with np.errstate(invalid="ignore"):
        v, u = np.nonzero(window @ pose[2, :3].astype(np.float32) + np.float32(pose[2, 3]) > floor_clearance)
    cell, inside = _cells(window[v, u], pose, area_low, settings.cell, shape)
    covered = inside.copy()
    covered[inside] = grid[cell[inside, 0], cell[inside, 1]]
    mask[v[covered] + rows.start, u[covered] + cols.start] = True
    return mask


def _standing(window: NDArray[np.float32], pose: Array, above: float) -> NDArray[np.float32]:
    """Points (optical frame) of a window higher than `above` (m) in the map."""
    with np.errstate(invalid="ignore"):
        tall = window @ pose[2, :3].astype(np.float32) + np.float32(pose[2, 3]) > above
    return window[tall]


def _cells(
    points: NDArray[np.float32], pose: Array, origin: Array, size: float, shape: NDArray[np.int64]
) -> tuple[NDArray[np.int64], Mask]:
    """Grid cells (x, y) of optical-frame points in the map, and which lie inside the grid."""
    xy = points @ pose[:2, :3].T.astype(np.float32) + pose[:2, 3].astype(np.float32)
    cell = np.floor((xy - origin[:2].astype(np.float32)) / size).astype(np.int64)
    return cell, np.all((cell >= 0) & (cell < shape), axis=1)


def inside_robots(points: Array, robots: Sequence[OverheadPose], settings: RobotMaskSettings) -> Mask:
    """Which points (N, 3, map) lie in a robot's box grown by its localization error."""
    inside = np.zeros(len(points), dtype=bool)
    sx, sy, sz = settings.size
    # a heading error turns the box's corners by up to half its diagonal times the error
    grow = settings.position_error + 0.5 * math.hypot(sx, sy) * math.sin(settings.yaw_error)
    for robot in robots:
        c, s = math.cos(robot.yaw), math.sin(robot.yaw)
        dx, dy = points[:, 0] - robot.x, points[:, 1] - robot.y
        along, across = c * dx + s * dy, -s * dx + c * dy
        inside |= (
            (np.abs(along) <= sx / 2 + grow)
            & (np.abs(across) <= sy / 2 + grow)
            & (points[:, 2] <= sz + settings.position_error)
        )
    return inside


def near_robot_points(points: Array, robot_points: Array, reach: float) -> Mask:
    """Which `points` (N, 3) lie within `reach` of one of `robot_points` (M, 3).

    A point inside a robot's grown box that lies on S_a's surfaces may be a tile's or the robot's
    face passing where a tile's would be. A robot's face goes on beyond the tile's place (it is
    35 cm tall), so the robot's own points, off S_a's surfaces, lie right beside it; a tile's face
    a few centimetres from any of them is the tile's (the grown box alone swallowed half of a
    structure a robot stood beside).
    """
    if len(points) == 0 or len(robot_points) == 0:
        return np.zeros(len(points), dtype=bool)
    distance, _ = cKDTree(robot_points).query(points, distance_upper_bound=reach)
    return np.isfinite(distance)


class RobotBoxes:
    """The other robots as boxes (their localization error added) for ray casting."""

    def __init__(self, robots: Sequence[OverheadPose], settings: RobotMaskSettings) -> None:
        from tiling_assembly.open3d_loader import import_open3d

        o3d = import_open3d()
        self._core = o3d.core
        self.robots = list(robots)
        self.settings = settings
        self.scene = o3d.t.geometry.RaycastingScene()
        sx, sy, sz = settings.size
        half = np.array([sx / 2, sy / 2]) + settings.position_error
        corners = np.array([[x, y, z] for z in (0.0, sz) for y in (-1, 1) for x in (-1, 1)], dtype=float)
        triangles = np.array(
            [[0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], [0, 1, 4], [1, 5, 4],
             [2, 6, 3], [3, 6, 7], [0, 4, 2], [2, 4, 6], [1, 3, 5], [3, 7, 5]],
            dtype=np.uint32,
        )
        for robot in self.robots:
            c, s = math.cos(robot.yaw), math.sin(robot.yaw)
            local = corners * np.array([half[0], half[1], 1.0])
            world = local @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]).T + (robot.x, robot.y, 0.0)
            self.scene.add_triangles(
                self._core.Tensor(world.astype(np.float32)), self._core.Tensor(triangles)
            )

    def depth(self, origin: Array, directions: NDArray[np.float32]) -> NDArray[np.float32]:
        """Distance parameter t of the first robot hit along each ray (inf: none)."""
        if not self.robots:
            return np.full(directions.shape[:-1], np.inf, dtype=np.float32)
        rays = np.empty((*directions.shape[:-1], 6), dtype=np.float32)
        rays[..., :3], rays[..., 3:] = origin, directions
        return self.scene.cast_rays(self._core.Tensor.from_numpy(rays))["t_hit"].numpy()

    def blocks(self, x: float, y: float, clearance: float) -> bool:
        """Whether a base at (x, y) would come within `clearance` (m) of a robot's box."""
        sx, sy, _ = self.settings.size
        for robot in self.robots:
            c, s = math.cos(robot.yaw), math.sin(robot.yaw)
            along, across = c * (x - robot.x) + s * (y - robot.y), -s * (x - robot.x) + c * (y - robot.y)
            gap = math.hypot(max(abs(along) - sx / 2, 0.0), max(abs(across) - sy / 2, 0.0))
            if gap < clearance + self.settings.position_error:
                return True
        return False
