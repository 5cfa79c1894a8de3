"""A tile where it should be against the tile where its points put it, pixel by pixel (beyond the
paper; its section 5 names "identification of incorrect assembly placements" as future work).

`misplacement` refits a tile on its points. When the tile slipped far (a small triangle shifted
4 cm), little of it still covers its place: its pixels see through where it should be, and taken
alone they say "missing". The refit says "moved", but a refit can also slide a tile that is gone
onto surfaces of the same height nearby. The depth image tells the two apart: ray cast S_a once
more with the tile at its fitted pose, and judge its pixels there as everywhere else
(`evidence.pixel_evidence`). A tile that really lies there has its surface measured where the
fitted pose puts it; a tile that is gone leaves the floor or the tiles below behind the fitted
pose too.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from tiling_assembly.geometry import PlacedTile
from vi_node.camera_model import PinholeCamera
from vi_node.evidence import EvidenceSettings, judgeable, pixel_evidence
from vi_node.misplacement import moved_tile
from vi_node.raycast import VirtualScene

Array = NDArray[np.float64]


@dataclass(frozen=True)
class PosePixels:
    """One tile's pixels at one pose: how many the measurement explains and how many see through."""

    agree: int
    against: int  # measured behind it, or blank where only "gone" explains a blank

    @property
    def decisive(self) -> int:
        return self.agree + self.against


@dataclass(frozen=True)
class DepthImage:
    """A scan's organised cloud with the camera that took it, its pose and the window on S_a."""

    cloud: NDArray[np.float32]  # (H, W, 3) optical frame
    camera: PinholeCamera
    pose: Array  # 4x4 optical frame in map
    window: tuple[slice, slice]  # rows, cols
    masked: NDArray[np.bool_] | None = None  # window-sized: pixels of other things (robots)


def pixels_at_fitted_pose(
    tiles: Sequence[PlacedTile],
    index: int,
    offset: tuple[float, float, float],
    image: DepthImage,
    settings: EvidenceSettings,
    ranges: tuple[float, float],
) -> PosePixels:
    """The pixel evidence for tile `index` of S_a (`tiles`) moved by `offset` (x, y, yaw)."""
    moved = [moved_tile(tile, offset) if k == index else tile for k, tile in enumerate(tiles)]
    scene = VirtualScene(moved)
    rows, cols = image.window
    virtual = scene.cast(image.camera, image.pose, rows, cols, *ranges)
    virtual = scene.look_behind(virtual, image.camera, image.pose, where=judgeable(virtual, settings, image.masked))
    evidence = pixel_evidence(image.cloud, virtual, len(moved), settings, None, image.masked)
    return PosePixels(agree=int(evidence.agree[index]), against=int(evidence.see_through[index]))


def fitted_pose_explains(planned_agree: int, fitted: PosePixels, share: float, gain: float,
                         min_pixels: int) -> bool:
    """Whether the fitted pose explains the tile's pixels: most of its decisive pixels agree there,
    and clearly more than agree with the planned pose."""
    if fitted.decisive < min_pixels:
        return False
    return fitted.agree >= share * fitted.decisive and fitted.agree >= planned_agree + gain * fitted.decisive
