"""Prioritized exploration: where the VI robot looks next (paper section 2.2).

"The VI-robot ... runs a prioritized exploration algorithm, which aims to map and update the
dynamically changing physical structure with priority on currently targeted building regions."
And: "If a tile is in state 'occluded', the VI-robot has to re-scan the building from a different
position before the building process can proceed."

Each expected tile carries a priority: highest just after a robot reported it placed (it has to be
checked) or reported it absent (a robot could not place on it: a scan should confirm), high while
its state is undetermined (occluded, or never seen) or a single scan called it missing (to be
confirmed, preferably from elsewhere), high again once it was seen a while ago and a tile a
robot is placing or about to place rests on it (the currently targeted building region: a
support gone missing stops that placement, and a scan should find it before the robot does), and
otherwise growing with the time since it was last seen, so that every tile is looked at again now
and then (tiles can disappear while building). Candidate viewpoints stand on rings around the structure, facing
it; the next one is the candidate whose view (predicted by ray tracing S_a, see
`viewpoint.rank_viewpoints`) resolves the most priority, less a small cost for driving there.

Several VI robots (the paper's N_s) divide the work by claims rather than by fixed sectors of the
ring: each explorer announces the viewpoint it drives to, and the others leave every viewpoint within
`claim_clearance` of it alone and count the tiles that view will resolve at `shared_weight` of their
priority. A viewpoint nearer another VI robot than this one counts `shared_weight` of its gain too,
so that at the start, before any claim is heard, each begins on its own side. So they look from
different places at different tiles, yet all of them can go where the building happens (a fixed
split of the ring would idle the robot whose sector is finished), and a tile one robot called
missing is still worth a look from a second robot elsewhere (the auction node confirms from two
camera positions). A claim that is never renewed (its robot died) lapses.

The ray traced view predicts S_a only: a tile a scan left undetermined where the prediction resolved
it is hidden by something unexpected (a wrong tile lying on the structure, a robot standing still)
that will hide it again. For `blind_memory` s that place is not counted on to resolve that tile
(`gain`): a VI robot otherwise looked 240 times from one place at two tiles an octagon, placed
instead of a triangle above them, hid from there, and never saw the octagon from elsewhere.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from tiling_assembly.structure import Structure

Pose2 = tuple[float, float, float]  # x, y, yaw of base_link in map

PRESENT, MISSING, OCCLUDED, UNKNOWN = "present", "missing", "occluded", "unknown"


def ring_viewpoints(structure: Structure, radii: Sequence[float], count: int) -> list[Pose2]:
    """Base poses on circles around the structure's centre, each facing the centre."""
    lo, hi = structure.bounds
    cx, cy = (lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2
    poses = []
    for ring, radius in enumerate(radii):
        offset = math.pi / count * (ring % 2)  # stagger the rings
        for k in range(count):
            angle = offset + 2 * math.pi * k / count
            x, y = cx + radius * math.cos(angle), cy + radius * math.sin(angle)
            poses.append((x, y, math.atan2(cy - y, cx - x)))
    return poses


@dataclass(frozen=True)
class PriorityWeights:
    just_placed: float = 4.0  # placed since it was last judged
    undetermined: float = 2.0  # occluded or never judged
    suspected: float = 4.0  # a robot found it absent since it was last judged
    stale_time: float = 60.0  # s after which a tile seen present is worth 1 again
    next_support: float = 3.0  # a tile a robot is about to place rests on it ...
    support_recheck: float = 20.0  # ... and it was last judged this many s ago (less: a share of it)


@dataclass
class TileKnowledge:
    state: str = UNKNOWN
    judged_at: float = -math.inf  # s, when a scan last judged it
    placed_at: float = -math.inf  # s, when a robot last reported it placed
    suspected_at: float = -math.inf  # s, when a robot last reported it absent


@dataclass
class Exploration:
    """What the VI robot knows about each expected tile, and the choice of the next viewpoint."""

    weights: PriorityWeights = field(default_factory=PriorityWeights)
    travel_cost: float = 0.5  # priority points per metre of driving
    failure_memory: float = 30.0  # s a viewpoint whose scans did not align is avoided
    claim_clearance: float = 0.5  # m: a viewpoint this near one another VI robot claimed is left to it
    shared_weight: float = 0.25  # share of its priority a tile keeps that another robot's claimed view resolves
    blind_memory: float = 60.0  # s a place whose scan left a tile undetermined is not counted on to resolve it ...
    blind_radius: float = 0.3  # m ... nor any place this near it
    tiles: dict[int, TileKnowledge] = field(default_factory=dict)
    left_undetermined: dict[int, list[tuple[float, float, float]]] = field(default_factory=dict)  # tile -> x, y, s
    failed: dict[int, float] = field(default_factory=dict)  # candidate index -> when it failed
    next_supports: frozenset[int] = frozenset()  # tiles the robots' next placements rest on

    def viewpoint_failed(self, index: int, now: float) -> None:
        """No scan from candidate `index` could be judged (not aligned, nothing in view)."""
        self.failed[index] = now

    def expect(self, tile_ids: Iterable[int]) -> None:
        """The tiles S_a holds now (others are forgotten)."""
        keep = set(tile_ids)
        for tile in keep - set(self.tiles):
            self.tiles[tile] = TileKnowledge()
        for tile in set(self.tiles) - keep:
            del self.tiles[tile]

    def placed(self, tile_id: int, now: float) -> None:
        self.tiles.setdefault(tile_id, TileKnowledge()).placed_at = now

    def suspected(self, tile_id: int, now: float) -> None:
        """A robot found `tile_id` physically absent (it could not place a tile on it)."""
        if tile_id in self.tiles:
            self.tiles[tile_id].suspected_at = now

    def targeted(self, supports: Iterable[int]) -> None:
        """The tiles the placements the robots work on now rest on: the currently targeted building
        region, where a tile gone missing stops the build (a robot finds it before a scan did)."""
        self.next_supports = frozenset(supports)

    def judged(self, states: dict[int, str], now: float, view: tuple[float, float] | None = None) -> None:
        """A scan looked at these tiles (only those it saw: not the repeats of a fused report), from a
        camera at `view` (x, y), if known."""

        for tile_id, state in states.items():
            if tile_id in self.tiles:
                knowledge = self.tiles[tile_id]
                knowledge.state, knowledge.judged_at = state, now
            if view is not None and state in (OCCLUDED, UNKNOWN):
                recent = [v for v in self.left_undetermined.get(tile_id, []) if now - v[2] < self.blind_memory]
                self.left_undetermined[tile_id] = [*recent, (view[0], view[1], now)]

    def gain(self, pose: Pose2, resolves: Iterable[int], priority: Mapping[int, float], now: float) -> float:
        """The priority a viewpoint predicted to resolve the tiles `resolves` is worth: the tiles a scan
        from near there left undetermined within `blind_memory` s aside."""
        return sum(priority.get(t, 0.0) for t in resolves if not self._blind(t, pose, now))

    def _blind(self, tile_id: int, pose: Pose2, now: float) -> bool:
        return any(now - at < self.blind_memory and math.dist(pose[:2], (x, y)) < self.blind_radius
                   for x, y, at in self.left_undetermined.get(tile_id, ()))

    def as_of(self, now: float, among: Iterable[int] | None = None) -> dict[int, TileKnowledge]:
        """What was known of each tile at `now` (s; `among`: the tiles S_a held then, None: every tile
        known): placements and absences reported for a later time had not happened yet. A choice made
        on a scan's states is made as of that scan's time, whatever news came in while it was judged
        (on a busy host more of it), so the VI robot takes the same path on a quiet host and a busy one."""
        out = {}
        for tile_id in self.tiles if among is None else among:
            k = self.tiles.get(tile_id, TileKnowledge())
            if k.placed_at > now or k.suspected_at > now:
                k = replace(k, placed_at=k.placed_at if k.placed_at <= now else -math.inf,
                            suspected_at=k.suspected_at if k.suspected_at <= now else -math.inf)
            out[tile_id] = k
        return out

    def priority(self, now: float, left_to_others: Collection[int] = (),
                 among: Iterable[int] | None = None) -> dict[int, float]:
        """Weight of seeing each expected tile (`among`, see `as_of`) at `now`; the tiles
        `left_to_others` (another VI robot's claimed view resolves them) keep `shared_weight` of it."""
        out = self._own_priority(now, among)
        for tile_id in left_to_others:
            if tile_id in out:
                out[tile_id] *= self.shared_weight
        return out

    def _own_priority(self, now: float, among: Iterable[int] | None) -> dict[int, float]:
        w = self.weights
        out = {}
        for tile_id, k in self.as_of(now, among).items():
            if k.suspected_at > k.judged_at:
                out[tile_id] = w.suspected
            elif k.placed_at > k.judged_at:
                out[tile_id] = w.just_placed
            elif k.state in (OCCLUDED, UNKNOWN, MISSING):  # a missing call wants confirming
                out[tile_id] = w.undetermined
            else:
                out[tile_id] = min(1.0, (now - k.judged_at) / w.stale_time)
                if tile_id in self.next_supports:
                    recheck = w.next_support * min(1.0, (now - k.judged_at) / w.support_recheck)
                    out[tile_id] = max(out[tile_id], recheck)
        return out

    def unresolved(self, now: float = math.inf, among: Iterable[int] | None = None) -> list[int]:
        """The expected tiles (`among`, see `as_of`) not seen in place since they were placed or
        reported absent, as of `now` (s)."""
        return sorted(
            t for t, k in self.as_of(now, among).items()
            if max(k.placed_at, k.suspected_at) > k.judged_at or k.state in (OCCLUDED, UNKNOWN, MISSING)
        )

    def choose(
        self, candidates: Sequence[Pose2], here: Pose2, now: float, gains: Sequence[float],
        claimed: Sequence[Pose2] = (), neighbours: Sequence[Pose2] = (),
    ) -> tuple[int, float]:
        """Index of the best candidate and its score.

        `gains[i]` is the priority candidate i would resolve (`viewpoint.rank_viewpoints` with the
        weights of `priority`); driving there costs `travel_cost` per metre. Candidates that failed
        recently, or lie within `claim_clearance` of a viewpoint another VI robot `claimed`, are
        skipped (all of them skipped: the first one is returned); the place the robot stands at
        counts half its gain; one nearer another VI robot (`neighbours`, where they stand) than
        `here`, `shared_weight` of it.
        """
        best, best_score = 0, -math.inf
        for index, (pose, gain) in enumerate(zip(candidates, gains, strict=True)):
            if now - self.failed.get(index, -math.inf) < self.failure_memory:
                continue
            if any(math.dist(pose[:2], other[:2]) < self.claim_clearance for other in claimed):
                continue
            distance = math.dist(here[:2], pose[:2])
            if any(math.dist(other[:2], pose[:2]) < distance for other in neighbours):
                gain *= self.shared_weight
            if distance < 0.05:  # a second look from the same place tells little new, and a
                gain *= 0.5  # missing call is confirmed from another camera position
            score = gain - self.travel_cost * distance
            if score > best_score + 1e-9:
                best, best_score = index, score
        return best, best_score


def nearest(candidates: Sequence[Pose2], pose: Pose2) -> int:
    return int(np.argmin([math.dist(c[:2], pose[:2]) for c in candidates]))
