"""Where the depth camera would return a point, with each tile there and with it gone (beyond paper
section 2.2.2: the virtual scan C_v predicts depths; this predicts the blanks too).

A Kinect v1 returns nothing outside its range (0.5-4.5 m), on surfaces seen at grazing incidence
(beyond ~75 degrees), and where its IR projector, 7.5 cm beside the IR camera, cannot light the
surface (HARDWARE.md). So a blank pixel is evidence too: on a thin top-layer tile seen from a low
camera, the rays through the tile's place end, once it is gone, on the tops of its supports or on
the floor at grazing incidence, and the camera returns nothing there. When the virtual scan with
the tile predicts a sure return and the one without it predicts a sure blank, a blank counts
against the tile (`evidence`). A blank that both hypotheses leave unexplained (something nearer
than 0.5 m, the projector shadow of an object that is not in S_a) says nothing.

Per pixel of the scan's window and for both hypotheses, `expect_returns` says whether a return is
sure (in range with a margin, seen at most `sure_incidence` obliquely, lit by the projector) or a
blank is sure (nothing hit, out of range, beyond `blank_incidence`, or in the projector's shadow).
Between the two, the camera may or may not return: such pixels decide nothing by their blanks.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from vi_node.camera_model import PinholeCamera
from vi_node.raycast import UNSEEN, SurfaceLayer, VirtualScan, VirtualScene

Array = NDArray[np.float64]
Mask = NDArray[np.bool_]


@dataclass(frozen=True)
class ReturnSettings:
    """When the camera returns a point (Kinect v1 defaults, HARDWARE.md)."""

    min_range: float = 0.5  # m
    max_range: float = 4.5  # m
    range_margin: float = 0.03  # m: this close to a range limit, a return is not sure either way
    sure_incidence: float = 1.13  # rad (65 deg): surfaces seen less obliquely return
    blank_incidence: float = 1.22  # rad (70 deg): surfaces seen more obliquely return nothing
    projector_offset: float = 0.075  # m, the IR projector along the optical x axis (+: right)


@dataclass(frozen=True)
class ReturnExpectation:
    """Per pixel of a virtual scan's window: sure return / sure blank, with the tiles there
    (`present_*`) and, on tile pixels, with that pixel's tile gone (`absent_*`)."""

    present_returns: Mask
    present_blank: Mask
    absent_returns: Mask
    absent_blank: Mask


def expect_returns(
    virtual: VirtualScan,
    scene: VirtualScene,
    camera: PinholeCamera,
    pose: Array,
    settings: ReturnSettings,
    where: Mask | None = None,
) -> ReturnExpectation:
    """Sure returns and sure blanks of both hypotheses (needs `virtual.behind`, see `look_behind`),
    on the pixels `where` (window-sized; default all): the projector's shadows are traced there only,
    elsewhere the answers do not account for them."""
    behind = virtual.behind
    if behind is None:
        raise ValueError("expect_returns needs the virtual scan's behind layer (VirtualScene.look_behind)")
    where = np.ones(virtual.tile.shape, dtype=bool) if where is None else where
    rays = camera.rays[virtual.rows, virtual.cols]  # optical frame
    projector = pose[:3, 3] + settings.projector_offset * pose[:3, 0]
    on_tile = virtual.tile >= 0
    front_lit = _lit(virtual.front, where & np.isfinite(virtual.depth), rays, pose, projector, scene, None)
    behind_lit = _lit(
        behind, where & on_tile & np.isfinite(behind.depth), rays, pose, projector, scene, virtual.tile
    )
    present_returns, present_blank = _sure(virtual.front, front_lit, settings)
    absent_returns, absent_blank = _sure(behind, behind_lit, settings)
    # off the tiles, removing "that pixel's tile" changes nothing
    absent_returns = np.where(on_tile, absent_returns, present_returns)
    absent_blank = np.where(on_tile, absent_blank, present_blank)
    return ReturnExpectation(present_returns, present_blank, absent_returns, absent_blank)


def _sure(layer: SurfaceLayer, lit: Mask, settings: ReturnSettings) -> tuple[Mask, Mask]:
    """Sure return and sure blank of one surface layer."""
    hit = np.isfinite(layer.depth)
    unseen = layer.tile == UNSEEN
    with np.errstate(invalid="ignore"):
        in_range = (layer.depth >= settings.min_range + settings.range_margin) & (
            layer.depth <= settings.max_range - settings.range_margin
        )
        out_of_range = (layer.depth < settings.min_range - settings.range_margin) | (
            layer.depth > settings.max_range + settings.range_margin
        )
    cos = layer.cos_incidence
    returns = hit & in_range & lit & (cos >= math.cos(settings.sure_incidence))
    blank = ~hit | out_of_range | (hit & ~lit) | (hit & (cos <= math.cos(settings.blank_incidence)))
    return returns, blank & ~returns & ~unseen


def _lit(
    layer: SurfaceLayer,
    hit: Mask,
    rays: NDArray[np.floating],
    pose: Array,
    projector: Array,
    scene: VirtualScene,
    ignore: NDArray[np.int64] | None,
) -> Mask:
    """Whether the projector lights the surface point of each `hit` pixel (True elsewhere); the
    surfaces of tile `ignore` (per pixel) do not shade it."""
    lit = np.ones(layer.depth.shape, dtype=bool)
    if not hit.any():
        return lit
    points = pose[:3, 3] + (rays[hit] * layer.depth[hit, None]).astype(np.float64) @ pose[:3, :3].T
    lit[hit] = ~scene.blocked(projector, points, None if ignore is None else ignore[hit])
    return lit
