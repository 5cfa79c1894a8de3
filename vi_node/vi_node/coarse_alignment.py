"""Coarse search of x, y and yaw before ICP (an addition to paper section 2.2.1).

The paper found the overhead and floor estimates "sufficient as a starting point" for ICP. With
the overhead errors it quotes (5 cm, 10 degrees) and a camera ~1 m from a 34 x 12 cm structure,
the yaw error alone moves the structure by up to ~20 cm in the image of the map: more than the
tiles are wide, so closest-point ICP locks onto the wrong tiles. After the floor correction only
x, y and yaw are uncertain, so a small exhaustive search is cheap: for every yaw hypothesis
(rotating the candidates about the camera's vertical axis, which leaves only the overhead
position error as translation), the candidates are binned into 1 cm voxels and cross-correlated
(FFT, all heights at once) with a model grid that rewards points near S_a's surface and penalises
points elsewhere. The best (yaw, shift) starts ICP within ~1 cm and ~1 degree.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.fft
from numpy.typing import NDArray

from vi_node.icp import yaw_shift_transform
from vi_node.raycast import VirtualScene

Array = NDArray[np.float64]


@dataclass(frozen=True)
class CoarseSettings:
    yaw_range: float = math.radians(12.0)  # search +- this about the prior's yaw
    yaw_step: float = math.radians(1.5)
    shift_range: float = 0.10  # m, search +- this in x and y
    cell: float = 0.01  # m, voxel size
    surface_band: float = 0.005  # m, points this close to S_a's surface count as on it
    off_penalty: float = 0.5  # what a point away from S_a (within its footprint) costs, relative to one on it
    footprint_margin: float = 0.02  # m around S_a's box where points away from its surfaces cost
    peak_spacing: int = 2  # hypotheses differ by more than this many yaw steps or shift cells
    max_points: int = 3000


@dataclass(frozen=True)
class CoarseResult:
    correction: Array  # 4x4 rigid transform of the map frame
    yaw: float
    shift: Array  # (2,)
    on_surface: float  # fraction of the points (within the model's grid) near S_a's surface after it
    on_surface_points: int  # how many points that is (of the subsample searched)


class CoarseAligner:
    """The model grid of one S_a, reused for every scan while S_a is unchanged."""

    def __init__(
        self,
        scene: VirtualScene,
        low: Array,
        high: Array,
        floor_clearance: float,
        settings: CoarseSettings | None = None,
    ) -> None:
        self.settings = s = settings or CoarseSettings()
        pad = s.shift_range + s.surface_band + 2 * s.cell
        self.origin = np.array([low[0] - pad, low[1] - pad, floor_clearance])
        size = np.array(
            [
                high[0] - low[0] + 2 * pad,
                high[1] - low[1] + 2 * pad,
                high[2] + s.surface_band - floor_clearance,
            ]
        )
        self.shape = tuple(int(n) for n in np.maximum(np.ceil(size / s.cell), 1).astype(int))
        nx, ny, nz = self.shape
        ix, iy, iz = np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij")
        centres = self.origin + (np.stack([ix, iy, iz], axis=-1) + 0.5) * s.cell
        if scene.has_tiles:
            core = scene._core
            distance = (
                scene.closest_scene.compute_distance(core.Tensor(centres.reshape(-1, 3).astype(np.float32)))
                .numpy()
                .reshape(nx, ny, nz)
            )
        else:
            distance = np.full((nx, ny, nz), np.inf)
        near = distance <= s.surface_band + 0.5 * s.cell
        self.near = near
        # points away from S_a's surfaces cost only inside its footprint: clutter and robots around
        # it would otherwise favour the shifts that move them off the grid
        footprint = np.all(
            (centres[..., :2] >= low[:2] - s.footprint_margin) & (centres[..., :2] <= high[:2] + s.footprint_margin),
            axis=-1,
        )
        model = np.where(near, 1.0, np.where(footprint, -s.off_penalty, 0.0)).transpose(2, 0, 1)  # (nz, nx, ny)
        self.model_spectrum = scipy.fft.rfft2(model.astype(np.float32), workers=2)
        self.yaws = np.arange(-s.yaw_range, s.yaw_range + 1e-9, s.yaw_step)
        reach = round(s.shift_range / s.cell)
        sx = np.fft.fftfreq(nx, 1.0 / nx).astype(int)
        sy = np.fft.fftfreq(ny, 1.0 / ny).astype(int)
        self.window = (np.abs(sx)[:, None] <= reach) & (np.abs(sy)[None, :] <= reach)
        self.shift_x, self.shift_y = sx, sy

    def align(self, points: Array, pivot: Array) -> CoarseResult | None:
        """The best yaw about `pivot` (the camera) and x, y shift for `points` (N, 3, map frame)."""
        found = self.hypotheses(points, pivot, 1)
        return found[0] if found else None

    def hypotheses(self, points: Array, pivot: Array, count: int) -> list[CoarseResult]:
        """The `count` best yaws about `pivot` (the camera), each with its best x, y shift, best
        first. Near the best score the 1 cm cells cannot tell a degree of yaw from a centimetre of
        shift: the alignment refines several of them and keeps the one that fits S_a best."""
        s = self.settings
        if len(points) > s.max_points:
            points = points[:: math.ceil(len(points) / s.max_points)]
        nx, ny, nz = self.shape
        iz = np.floor((points[:, 2] - self.origin[2]) / s.cell).astype(np.int64)
        keep = (iz >= 0) & (iz < nz)
        points, iz = points[keep], iz[keep]
        if len(points) == 0:
            return []
        rel = points[:, :2] - pivot[:2]
        cos, sin = np.cos(self.yaws)[:, None], np.sin(self.yaws)[:, None]
        x = cos * rel[:, 0] - sin * rel[:, 1] + pivot[0]
        y = sin * rel[:, 0] + cos * rel[:, 1] + pivot[1]
        ix = np.floor((x - self.origin[0]) / s.cell).astype(np.int64)
        iy = np.floor((y - self.origin[1]) / s.cell).astype(np.int64)
        inside = (ix >= 0) & (ix < nx) & (iy >= 0) & (iy < ny)
        hypothesis = np.broadcast_to(np.arange(len(self.yaws))[:, None], ix.shape)
        flat = ((hypothesis * nz + iz) * nx + ix) * ny + iy
        counts = np.bincount(flat[inside], minlength=len(self.yaws) * nz * nx * ny)
        grid = np.minimum(counts, 3).reshape(len(self.yaws), nz, nx, ny).astype(np.float32)
        spectrum = np.conj(scipy.fft.rfft2(grid, workers=2)) * self.model_spectrum[None]
        # (yaws, nx, ny): sum_v M(v) K(v + s) for every shift s
        score = scipy.fft.irfft2(spectrum.sum(axis=1), s=(nx, ny), workers=2)
        score = np.where(self.window[None], score, -np.inf)
        chosen = self._distinct_peaks(score, count)
        return [self._result(h, cell, ix[h], iy[h], iz, pivot) for h, cell in chosen]

    def _distinct_peaks(self, score: Array, count: int) -> list[tuple[int, int]]:
        """The `count` best (yaw index, flat shift cell) pairs, each at least `peak_spacing` yaw
        steps or shift cells from the ones before it (greedy non-maximum suppression; plateaus of
        equal scores give one pair, the smaller turn first)."""
        s = self.settings
        _, ny, _ = self.shape
        h, cells = np.nonzero(np.isfinite(score.reshape(len(self.yaws), -1)))
        values = score.reshape(len(self.yaws), -1)[h, cells]
        order = np.lexsort((np.abs(self.yaws[h]), -np.round(values, 6)))
        h, cells = h[order], cells[order]
        sx, sy = self.shift_x[cells // ny], self.shift_y[cells % ny]
        chosen: list[tuple[int, int]] = []
        alive = np.ones(len(h), dtype=bool)
        while len(chosen) < count and alive.any():
            k = int(np.argmax(alive))
            chosen.append((int(h[k]), int(cells[k])))
            alive &= ~(
                (np.abs(h - h[k]) <= s.peak_spacing)
                & (np.abs(sx - sx[k]) <= s.peak_spacing)
                & (np.abs(sy - sy[k]) <= s.peak_spacing)
            )
        return chosen

    def _result(
        self, h: int, cell: int, ix: NDArray[np.int64], iy: NDArray[np.int64], iz: NDArray[np.int64], pivot: Array
    ) -> CoarseResult:
        nx, ny, _ = self.shape
        shift = np.array([self.shift_x[cell // ny], self.shift_y[cell % ny]], dtype=float) * self.settings.cell
        ux, uy = ix + self.shift_x[cell // ny], iy + self.shift_y[cell % ny]
        ok = (ux >= 0) & (ux < nx) & (uy >= 0) & (uy < ny)
        near = int(self.near[ux[ok], uy[ok], iz[ok]].sum())
        yaw = float(self.yaws[h])
        return CoarseResult(
            yaw_shift_transform(yaw, pivot, shift), yaw, shift, near / max(1, int(ok.sum())), near
        )
