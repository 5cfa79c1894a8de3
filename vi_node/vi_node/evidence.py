"""Per-pixel evidence: which of two hypotheses explains each measured pixel (beyond paper section 2.2.3).

The paper compares only how many points support each tile. Here every pixel the virtual scan C_v
gives to tile i is judged between two hypotheses, "tile i is there" (the virtual scan's depth) and
"tile i is gone" (the first surface behind it, `VirtualScene.look_behind`), each with a tolerance
that follows the Kinect's noise at that depth and obliquity:

- measured where only "there" explains it: the tile's surface is there (agree);
- measured where both explain it (the surface revealed behind a thin tile often lies within the
  noise of its face): ambiguous, evidence of nothing;
- measured clearly *behind* the tile's face: the camera sees through where the tile should be
  (see-through, against the tile);
- measured clearly *in front*: something else hides it (in front, no evidence either way);
- no return where "there" predicts a sure return and "gone" a sure blank (`expected_returns`), in a
  blank region that these predictions explain: the tile is gone (blank, against the tile);
- any other blank: no evidence (no return). A blank region holding pixels where every hypothesis
  predicts a sure return is the doing of something S_a does not hold (an object nearer than the
  camera's 0.5 m, the projector shadow of a robot): none of its pixels count.

Only pixels away from depth edges of the tile-there scan (where a pixel of lateral noise or of pose
error flips the answer), not at grazing incidence and not on a masked robot are judged; the
tile-gone depth is taken over the pixel's neighbourhood for the same reason. Tiles are then decided
relative to what the virtual scan predicts for them (so a 4 cm tile at 2 m, a few dozen pixels,
is judged on those), not on a fixed count; a present verdict never rests on a small share of
clear pixels among ambiguous ones.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, replace

import numpy as np
from numpy.typing import NDArray

from vi_node.classify import TileState
from vi_node.depth_noise import axial_sigma, disparity_step, resolved_motion
from vi_node.expected_returns import ReturnSettings
from vi_node.raycast import VirtualScan

Counts = NDArray[np.int64]
Mask = NDArray[np.bool_]


@dataclass(frozen=True)
class EvidenceSettings:
    depth_sigmas: float = 3.0  # agreement within this many axial noise sigmas ...
    depth_margin: float = 0.005  # m, ... plus this (model, placement and pose error), / cos(incidence)
    max_incidence: float = 1.43  # rad (82 deg): more oblique pixels are not judged
    min_observed_pixels: int = 8  # a tile needs this many decisive pixels ...
    min_observed_fraction: float = 0.15  # ... and this share of the pixels it should fill
    present_fraction: float = 0.7  # present when this share of the decisive pixels agree ...
    present_share: float = 0.3  # ... and they are this share of every pixel that saw its place
    # ... and this share of every judgeable pixel of the tile agrees, those robots hide included: two
    # robots by a structure hid an octagon lying in a triangle's place, which agreed on 29 of 598
    present_view_share: float = 0.15
    missing_fraction: float = 0.6  # missing when this share of the decisive pixels are against it
    # m: no pixel counts against a tile where the camera resolves no better (`depth_noise`; 2.6 m
    # deep): there the alignment's least turn moves a tile's edges by as much (a pier block in
    # place 2.9 m off saw past it on 15 of its 19 decisive pixels)
    against_resolution: float = 0.02
    returns: ReturnSettings = field(default_factory=ReturnSettings)


@dataclass
class TileEvidence:
    """Pixel counts per tile (arrays indexed like the expected model's tiles)."""

    agree: Counts
    see_through: Counts  # measured behind the tile's face
    in_front: Counts
    no_return: Counts  # blanks that say nothing
    judged: Counts  # pixels of the tile that were judged (interior, not grazing, in range)
    virtual: Counts  # v_i: every pixel the virtual scan gives the tile
    blank: Counts = field(default_factory=lambda: np.zeros(0, np.int64))  # blanks only "gone" explains
    ambiguous: Counts = field(default_factory=lambda: np.zeros(0, np.int64))  # both hypotheses explain
    judgeable: Counts = field(default_factory=lambda: np.zeros(0, np.int64))  # judged or hidden by a robot

    def __post_init__(self) -> None:
        for name in ("blank", "ambiguous", "judgeable"):
            if len(getattr(self, name)) != len(self.agree):
                setattr(self, name, np.zeros(len(self.agree), dtype=np.int64))

    @property
    def against(self) -> Counts:
        return self.see_through + self.blank

    @property
    def observed(self) -> Counts:
        """Decisive pixels: for the tile (agree) or against it."""
        return self.agree + self.against

    @classmethod
    def zeros(cls, count: int) -> TileEvidence:
        return cls(**{f.name: np.zeros(count, dtype=np.int64) for f in fields(cls)})

    def __add__(self, other: TileEvidence) -> TileEvidence:
        return TileEvidence(**{f.name: getattr(self, f.name) + getattr(other, f.name) for f in fields(self)})

    def unopposed(self, tiles: NDArray[np.bool_]) -> TileEvidence:
        """This evidence with nothing against `tiles`: their see-through and blank pixels say nothing."""
        return replace(self, see_through=np.where(tiles, 0, self.see_through), blank=np.where(tiles, 0, self.blank))

    def take(self, index: int) -> TileEvidence:
        """The evidence of one tile, as arrays of length 1."""
        s = slice(index, index + 1)
        return TileEvidence(**{f.name: getattr(self, f.name)[s] for f in fields(self)})

    def select(self, keep: NDArray[np.bool_]) -> TileEvidence:
        """The evidence of the tiles `keep` marks."""
        return TileEvidence(**{f.name: getattr(self, f.name)[keep] for f in fields(self)})


def depth_tolerance(
    depth: NDArray[np.float32], cos_incidence: NDArray[np.float32], settings: EvidenceSettings
) -> NDArray[np.float32]:
    """How far (m) a measured depth may lie from the virtual one and still be the same surface.

    Axial noise (Nguyen et al. 2012) and half a disparity step (Khoshelham 2012) at that depth,
    plus a margin for model and pose error that grows on oblique faces.
    """
    return (
        settings.depth_sigmas * axial_sigma(depth) + 0.5 * disparity_step(depth)
        + settings.depth_margin / np.maximum(cos_incidence, 0.2)
    ).astype(np.float32)


def smooth(depth: NDArray[np.float32]) -> Mask:
    """Pixels whose four neighbours are at nearly the same depth (not at a depth edge, not at the
    window's border): there a pixel of lateral noise or of pose error changes nothing."""
    inside = np.isfinite(depth)
    if inside.size == 0:
        return inside  # no pixels: the structure is out of this view (a viewpoint facing away)
    jump = 0.01 + 0.02 * np.where(np.isfinite(depth), depth, 0.0)
    with np.errstate(invalid="ignore"):  # inf - inf between two blank pixels: nan, compared False
        dy = np.abs(np.diff(depth, axis=0)) <= np.minimum(jump[1:, :], jump[:-1, :])  # False across inf
        dx = np.abs(np.diff(depth, axis=1)) <= np.minimum(jump[:, 1:], jump[:, :-1])
    inside[1:, :] &= dy
    inside[:-1, :] &= dy
    inside[:, 1:] &= dx
    inside[:, :-1] &= dx
    inside[0, :] = inside[-1, :] = False
    inside[:, 0] = inside[:, -1] = False
    return inside


def interior(tile: NDArray[np.int64], depth: NDArray[np.float32]) -> Mask:
    """Pixels of a tile away from depth edges (`smooth`). Between two tiles at the same depth
    (adjacent top faces) nothing is lost, so thin tiles seen from afar keep their pixels."""
    return (tile >= 0) & smooth(depth)


def judgeable(virtual: VirtualScan, settings: EvidenceSettings, masked: Mask | None = None) -> Mask:
    """Tile pixels (window-sized) to judge: away from depth edges, not at grazing incidence, not masked."""
    judged = interior(virtual.tile, virtual.depth) & (virtual.cos_incidence >= math.cos(settings.max_incidence))
    return judged if masked is None else judged & ~masked


def pixel_evidence(
    cloud: NDArray[np.float32],
    virtual: VirtualScan,
    tile_count: int,
    settings: EvidenceSettings,
    against_blank: Mask | None = None,
    masked: Mask | None = None,
) -> TileEvidence:
    """Judge every pixel of the virtual scan's tiles between "there" and "gone" (needs
    `virtual.behind` for "gone"; without it, only "there" is tested). `against_blank`
    (window-sized, from `blank_evidence`) are the blanks that count against their tile; `masked`
    marks pixels of other things (robots): nothing measured there counts for a tile, but a depth
    measured behind a tile's face still says the ray went through its place."""
    tile = virtual.tile
    counts = TileEvidence.zeros(tile_count)
    if tile.size == 0:
        return counts
    counts.virtual = np.bincount(tile[tile >= 0], minlength=tile_count).astype(np.int64)
    judged = judgeable(virtual, settings)
    if not judged.any():
        return counts
    measured = cloud[virtual.rows, virtual.cols, 2]
    blank = ~np.isfinite(measured)
    there = depth_tolerance(virtual.depth, virtual.cos_incidence, settings)
    with np.errstate(invalid="ignore"):
        difference = measured - virtual.depth
        fits_there = np.abs(difference) <= there
        fits_gone = _fits_gone(measured, virtual, settings)
        behind = ~blank & ~fits_there & (difference > 0)
        front = ~blank & ~fits_there & (difference < 0)
    if against_blank is None:
        against_blank = np.zeros(tile.shape, dtype=bool)
    free = np.ones(tile.shape, dtype=bool) if masked is None else ~masked
    owner = tile[judged]

    def count(mask: Mask) -> Counts:
        return np.bincount(owner[mask[judged]], minlength=tile_count).astype(np.int64)

    counts.judged = count(free | behind)
    counts.judgeable = count(judged)
    counts.agree = count(free & fits_there & ~fits_gone)
    counts.ambiguous = count(free & fits_there & fits_gone)
    counts.see_through = count(behind)
    counts.in_front = count(free & front)
    counts.blank = count(free & against_blank)
    counts.no_return = count(free & blank & ~against_blank)
    return counts


def unexpected(cloud: NDArray[np.float32], virtual: VirtualScan, settings: EvidenceSettings) -> Mask:
    """Window pixels measured clearly in front of what the virtual scan expects there: things S_a
    does not hold (a robot, a hand, a tile not yet reported)."""
    measured = cloud[virtual.rows, virtual.cols, 2]
    expected = np.where(np.isfinite(virtual.depth), virtual.depth, 1.0)
    tolerance = depth_tolerance(expected, virtual.cos_incidence, settings)
    with np.errstate(invalid="ignore"):
        return np.isfinite(measured) & (measured < virtual.depth - tolerance)


def _fits_gone(measured: NDArray[np.float32], virtual: VirtualScan, settings: EvidenceSettings) -> Mask:
    """Whether the tile-gone hypothesis explains each measured depth: within the tolerance of the
    depths seen behind the tile over the pixel's 3x3 neighbourhood (a pixel of lateral noise may
    show the revealed surface's neighbour; the tile's other neighbours are the same under both
    hypotheses, and the tile-there test keeps away from them)."""
    behind = virtual.behind
    if behind is None:
        return np.zeros(measured.shape, dtype=bool)
    tile = virtual.tile
    gone = behind.depth
    low, high = gone.copy(), gone.copy()
    rows, cols = tile.shape
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            if dy == dx == 0:
                continue
            here = (slice(max(0, -dy), rows - max(0, dy)), slice(max(0, -dx), cols - max(0, dx)))
            there = (slice(max(0, dy), rows - max(0, -dy)), slice(max(0, dx), cols - max(0, -dx)))
            same = (tile[there] == tile[here]) & np.isfinite(gone[there])
            low[here] = np.where(same, np.minimum(low[here], gone[there]), low[here])
            high[here] = np.where(same, np.maximum(high[here], gone[there]), high[here])
    finite = np.isfinite(behind.depth)
    tolerance = depth_tolerance(np.where(finite, behind.depth, 1.0), behind.cos_incidence, settings)
    return finite & (measured >= low - tolerance) & (measured <= high + tolerance)


def too_deep(depth: NDArray[np.float64], settings: EvidenceSettings) -> NDArray[np.bool_]:
    """Which tiles, at these depths (m) in the camera, lie where no pixel counts against them."""
    return resolved_motion(depth) > settings.against_resolution


def shown(evidence: TileEvidence, settings: EvidenceSettings) -> Mask:
    """Whether enough of each tile agrees to vouch for it, given how much of it the view would judge
    were no robot in the way (a wrong tile agrees with the planned one where they overlap)."""
    return evidence.agree >= settings.present_view_share * evidence.judgeable


def decide(evidence: TileEvidence, settings: EvidenceSettings) -> NDArray[np.int64]:
    """PRESENT, MISSING or OCCLUDED (undetermined) per tile from its pixel evidence.

    A tile is resolved when enough of the pixels the virtual scan predicts for it were decisive
    (agree, see-through or blank: in-front, ambiguous and uninformative blank pixels say nothing
    about it); then the share of agreeing or opposing pixels decides. A present verdict also needs
    the agreeing pixels to be a fair share of every pixel that saw the tile's place (ambiguous
    ones included), and of every pixel that would have, were no robot in the way.
    """
    observed = evidence.observed
    enough = (observed >= settings.min_observed_pixels) & (
        observed >= settings.min_observed_fraction * evidence.judged
    )
    agree = evidence.agree
    share_agree = agree / np.maximum(observed, 1)
    share_against = evidence.against / np.maximum(observed, 1)
    clear = (agree >= settings.present_share * (observed + evidence.ambiguous)) & shown(evidence, settings)
    state = np.full(len(observed), int(TileState.OCCLUDED), dtype=np.int64)
    state[enough & clear & (share_agree >= settings.present_fraction)] = TileState.PRESENT
    state[enough & (share_against >= settings.missing_fraction)] = TileState.MISSING
    return state
