"""How well a pose of the camera explains the depth image (an addition to paper sections 2.2.1-2.2.2).

The coarse x, y, yaw search and ICP score a pose by how many scan points lie near S_a's surfaces.
A view of a few flat tiles leaves that score flat: slid a few centimetres along their tops, or
turned a few degrees, the points still lie on some surface (the search's 1 cm cells cannot tell),
and the search's best hypotheses can all lie 6-10 degrees from the truth. The depth image tells
them apart: ray cast S_a from the pose (`raycast`) and compare each pixel's measured depth with
the virtual one. Pixels measured where S_a's surface is agree; pixels measured clearly *behind* a
surface of S_a say the camera saw through where the pose puts a tile. A misaligned pose puts
tiles in front of the floor and of other tiles that the camera saw, so it collects such pixels by
the hundred; the true pose has almost none. Pixels measured in front of S_a (robots, clutter,
tiles not yet reported) and blanks say nothing.

The score counts tile by tile, and the `MAY_BE_GONE` tiles seen through most cost a pose at worst
nothing: a tile may be gone, and then the true pose sees through all of its place. Counted over
the whole view, the few hundred pixels through a removed tile outweighed what the rest of the view
agreed, and the alignment preferred poses that slid other tiles into its place (a paper_14 team
recording: of the scans that showed a removed trapezoid's place, 5 failed to align and 2 aligned
3 cm off). A misaligned pose sees through parts of many tiles, each of which still agrees
elsewhere, so the cap costs it little. Not every tile: a pose slid by one period of a repetitive
structure then had its overhanging edge row for free (a pyramid_91 scan went 7.9 cm off), and
removals rarely take more than two tiles from one view.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from vi_node.camera_model import PinholeCamera
from vi_node.evidence import EvidenceSettings, depth_tolerance
from vi_node.icp import yaw_shift_transform
from vi_node.raycast import VirtualScene

Array = NDArray[np.float64]

MAY_BE_GONE = 2  # tiles per view whose seen-through pixels may be a removal's, not the pose's fault


@dataclass(frozen=True)
class ViewAgreement:
    """Pixels of S_a's tiles (at one pose, every `stride`-th pixel) the measurement explains or contradicts."""

    agree_by_tile: NDArray[np.int64]  # per tile (scene index): measured on its surface
    behind_by_tile: NDArray[np.int64]  # per tile: measured clearly behind it (seen through)

    @property
    def agree(self) -> int:
        return int(self.agree_by_tile.sum())

    @property
    def behind(self) -> int:
        return int(self.behind_by_tile.sum())

    def score(self, behind_weight: float, may_be_gone: int = MAY_BE_GONE) -> float:
        """Agreeing minus `behind_weight` times seen-through pixels, with the `may_be_gone` tiles
        seen through most costing at worst nothing (they may be gone)."""
        by_tile = self.agree_by_tile - behind_weight * self.behind_by_tile
        worst = np.sort(by_tile)[:may_be_gone]
        return float(by_tile.sum() - worst[worst < 0].sum())


@dataclass(frozen=True)
class DepthView:
    """What the score needs of one scan: its organised cloud, the camera and the pixels to ignore."""

    cloud: NDArray[np.float32]  # (H, W, 3) optical frame
    camera: PinholeCamera
    masked: NDArray[np.bool_] | None = None  # (H, W): pixels of other robots
    stride: int = 4


def view_agreement(
    view: DepthView,
    scene: VirtualScene,
    pose: Array,
    box: tuple[Array, Array],
    ranges: tuple[float, float],
    settings: EvidenceSettings,
) -> ViewAgreement:
    """Agreeing and contradicting pixels of S_a (`scene`, bounding `box`) seen from `pose`."""
    rows, cols = view.camera.box_roi(pose, *box)
    rows = slice(rows.start, rows.stop, view.stride)
    cols = slice(cols.start, cols.stop, view.stride)
    virtual = scene.cast(view.camera, pose, rows, cols, *ranges)
    on_tile = virtual.tile >= 0
    if view.masked is not None:
        on_tile &= ~view.masked[rows, cols]
    measured = view.cloud[rows, cols, 2][on_tile]
    expected = virtual.depth[on_tile]
    tolerance = depth_tolerance(expected, virtual.cos_incidence[on_tile], settings)
    with np.errstate(invalid="ignore"):  # blanks (NaN) compare False: they say nothing
        difference = measured - expected
        agree = np.abs(difference) <= tolerance
        behind = difference > tolerance
    tile = virtual.tile[on_tile]
    tiles = int(tile.max()) + 1 if tile.size else 0
    return ViewAgreement(np.bincount(tile[agree], minlength=tiles), np.bincount(tile[behind], minlength=tiles))


def climb(pose: Array, score: Callable[[Array], float], shift: float = 0.01, turn: float = np.radians(0.5),
          max_steps: int = 12) -> tuple[Array, float]:
    """`pose` moved step by step (`shift` m in x or y, `turn` rad of yaw about the camera) while the
    view agreement `score` rises; the pose it stops at and its score. ICP on a view of few side
    faces can stop a couple of centimetres off along them; the pixels it sees through then pull
    the pose back."""
    steps = [(0.0, (dx, dy)) for dx, dy in ((shift, 0.0), (-shift, 0.0), (0.0, shift), (0.0, -shift))]
    steps += [(dyaw, (0.0, 0.0)) for dyaw in (turn, -turn)]
    best, best_score = pose, score(pose)
    for _ in range(max_steps):
        moves = [yaw_shift_transform(dyaw, best[:3, 3], np.array(step)) @ best for dyaw, step in steps]
        scores = [score(move) for move in moves]
        top = int(np.argmax(scores))
        if scores[top] <= best_score:
            break
        best, best_score = moves[top], scores[top]
    return best, best_score

