"""Next viewpoint: which tiles would a scan from a candidate pose resolve (paper section 2.2.2,
turned around: the virtual Kinect K_v placed at a pose the VI robot could drive to).

A tile is resolvable from a pose when the ray-traced virtual scan of S_a from there puts at least
`min_support` points on it (scaled with the resolution used for the prediction): then the real
scan can tell present from missing; with fewer it stays occluded.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from tiling_assembly.geometry import PlacedTile
from vi_node.camera_model import PinholeCamera
from vi_node.pose_prior import CameraMount, OverheadPose, camera_prior
from vi_node.raycast import VirtualScene


class ViewPredictor:
    """Predicts per-tile virtual support from VI robot base poses, for one S_a."""

    def __init__(
        self,
        tiles: Sequence[PlacedTile],
        camera: PinholeCamera,
        mount: CameraMount,
        min_support: int,
        max_range: float = 4.5,
        min_range: float = 0.5,
        prediction_width: int = 160,
    ) -> None:
        self.tiles = list(tiles)
        self.scene = VirtualScene(self.tiles)
        scale = prediction_width / camera.width
        self.camera = camera.at_resolution(prediction_width, round(camera.height * scale))
        # support counts shrink with the number of pixels
        self.min_support = max(1.0, min_support * scale * scale)
        self.mount = mount
        self.range = (min_range, max_range)
        if self.tiles:
            lows = np.array([t.aabb[0] for t in self.tiles])
            highs = np.array([t.aabb[1] for t in self.tiles])
            self.box = (lows.min(axis=0), highs.max(axis=0))

    def support(self, base_pose: tuple[float, float, float]) -> dict[int, float]:
        """Predicted virtual support of every tile from `base_pose` (points at the prediction resolution)."""
        if not self.tiles:
            return {}
        pose = camera_prior(OverheadPose(*base_pose), self.mount)
        rows, cols = self.camera.box_roi(pose, *self.box)
        if rows.stop <= rows.start or cols.stop <= cols.start:
            return {t.tile_id: 0.0 for t in self.tiles}
        scan = self.scene.cast(self.camera, pose, rows, cols, *self.range)
        counts = scan.support(len(self.tiles))
        return {t.tile_id: float(c) for t, c in zip(self.tiles, counts, strict=True)}

    def resolvable(self, base_pose: tuple[float, float, float]) -> set[int]:
        """Tiles a scan from `base_pose` would see well enough to judge."""
        full = self.min_support
        return {tile for tile, count in self.support(base_pose).items() if count >= full}
