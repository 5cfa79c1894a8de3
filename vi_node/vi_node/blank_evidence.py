"""Which blank pixels count against a tile (beyond paper section 2.2.3; see `expected_returns`).

A blank pixel on tile i counts against it when, with every tile there, the camera would surely
return a point there, and with tile i gone it would surely return nothing (the rays then end on
grazing surfaces, out of range or in the projector's shadow). Unless something S_a does not hold
explains the blank as well, and the Kinect leaves such blanks around unexpected things:

- at their outline, where the depth jumps (a pixel of lateral noise, or a jump the Kinect drops),
  so blanks within a few pixels of a measured point in front of S_a, or of a masked robot, say
  nothing;
- in their projector shadow: the IR projector sits `projector_offset` beside the camera along its
  x axis, so a measured point at depth z_o at column u + k of the same row hides the point at
  column u and depth z from the projector when z_o <= 1 / (k / (f b) + 1 / z) (the projector's
  ray to it passes behind that point);
- where they are nearer than the camera's range: no depth at all, a blank blob. So tile i's blank
  must end where tile i's image ends: a blank that runs on, in the few pixels around it, over
  pixels where the scene with every tile there would surely return (and that are no depth edge of
  it), more than a few of them or more than return there, is some occluder's, and none of tile i's
  blanks count.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from vi_node.camera_model import PinholeCamera
from vi_node.expected_returns import ReturnExpectation
from vi_node.raycast import VirtualScan

Mask = NDArray[np.bool_]


@dataclass(frozen=True)
class BlankSettings:
    outline: int = 2  # px around an unexpected thing's outline where blanks say nothing
    ring: int = 4  # px around a tile's blanks that must not be unexplained blanks ...
    ring_share: float = 0.1  # ... beyond this share of them (and 2 px)


def blank_evidence(
    depth: NDArray[np.float32],
    virtual: VirtualScan,
    returns: ReturnExpectation,
    camera: PinholeCamera,
    projector_offset: float,
    unexpected: Mask,
    smooth: Mask,
    settings: BlankSettings | None = None,
) -> Mask:
    """Blank pixels (of the virtual scan's window) that count against their tile.

    `depth`: the whole measured depth image (NaN: blank); `unexpected`: window pixels of things S_a
    does not hold (measured clearly in front of it, or masked robots); `smooth`: window pixels away
    from depth edges of the virtual scan.
    """
    settings = settings or BlankSettings()
    blank = ~np.isfinite(depth[virtual.rows, virtual.cols])
    tile = virtual.tile
    candidate = blank & (tile >= 0) & returns.present_returns & returns.absent_blank
    if not candidate.any():
        return candidate
    if unexpected.any():
        candidate &= ~ndimage.binary_dilation(unexpected, iterations=settings.outline)
    candidate &= ~_in_shadow_of_measured(candidate, depth, virtual, camera, projector_offset)
    sure = returns.present_returns & smooth
    for index in np.unique(tile[candidate]):
        mine = candidate & (tile == index)
        if not _ends_with_the_tile(mine, tile == index, blank, sure, settings):
            candidate &= ~mine
    return candidate


def _ends_with_the_tile(mine: Mask, tile: Mask, blank: Mask, sure: Mask, settings: BlankSettings) -> bool:
    """Whether the tile's blank is a hole the size of the tile: within `ring` px around its blank
    pixels (off the tile), few blanks where a return was `sure`, and fewer of those than returns
    (a blank that swallows the tile's surroundings is something in front of the camera)."""
    rows, cols = np.nonzero(mine)
    r = settings.ring
    top, bottom = max(0, rows.min() - r), min(mine.shape[0], rows.max() + r + 1)
    left, right = max(0, cols.min() - r), min(mine.shape[1], cols.max() + r + 1)
    window = (slice(top, bottom), slice(left, right))
    ring = ndimage.binary_dilation(mine[window], iterations=r) & ~tile[window] & sure[window]
    odd = int(np.count_nonzero(ring & blank[window]))
    returned = int(np.count_nonzero(ring & ~blank[window]))
    return odd <= max(2.0, settings.ring_share * len(rows)) and (odd < 3 or odd <= returned)


def _in_shadow_of_measured(
    candidate: Mask, depth: NDArray[np.float32], virtual: VirtualScan, camera: PinholeCamera, offset: float
) -> Mask:
    """Candidate pixels (window) that a measured point of the same image row hides from the
    projector (see the module's docstring); the projector is at +x when `offset` > 0, so the hiding
    points lie at larger columns."""
    shadow = np.zeros(candidate.shape, dtype=bool)
    rows, cols = np.nonzero(candidate)
    expected = virtual.depth[rows, cols].astype(np.float64)
    fb = camera.fx * abs(offset)
    reach = int(np.ceil(np.max(fb * (1.0 / 0.3 - 1.0 / expected)))) if len(expected) else 0
    if reach <= 0:
        return shadow
    step = np.arange(1, reach + 1)
    side = 1 if offset > 0 else -1
    image_rows = rows + (virtual.rows.start or 0)
    look = cols[:, None] + (virtual.cols.start or 0) + side * step[None, :]
    width = depth.shape[1]
    inside = (look >= 0) & (look < width)
    values = depth[image_rows[:, None], np.clip(look, 0, width - 1)]
    hiding = np.where(inside & np.isfinite(values), values, np.inf)
    # depth of the projector's ray to the candidate's point where it passes column u + k
    ray_depth = 1.0 / (step[None, :] / fb + 1.0 / expected[:, None])
    shadow[rows, cols] = np.any(hiding <= ray_depth - 0.01, axis=1)
    return shadow
