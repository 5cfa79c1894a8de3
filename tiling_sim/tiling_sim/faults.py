"""Fault injection for the simulated testbed (paper section 3.2: "one or more random assembly tiles
were removed at different parts of the assembly process").

A seeded schedule of removal times per trial, and an optional chance that a tile slips from the
gripper during a placement (the placement then fails). The tile removed at each time is drawn
from the tiles that can be removed then (placed, nothing on top), with the same seeded generator,
so a trial is reproducible from its seed.

Beyond the paper (its future work): chosen tiles of a trial land wrong the first time they are
placed. A misplaced tile is shifted 2-5 cm in a random direction or turned 15-45 degrees about the
vertical (at most half its symmetry's turn: a turn by its symmetry leaves it as planned); a wrong
tile is a tile of another type of the same height, from the parts cache nearest
the right one (the mix-up a robot makes at neighbouring caches). The tiles and how each lands are
drawn from the seed and the tile alone, never from the order the robots happen to place them in, so
a trial's faults do not depend on how busy the host is; and with generators of their own, so that
a trial's removals and drops stay what they were without them.
"""

from __future__ import annotations

import math
import random
from dataclasses import dataclass, field

import networkx as nx

from tiling_assembly.geometry import turn_symmetry
from tiling_assembly.structure import Structure
from tiling_sim.world import Misplacement, PhysicalWorld

SHIFT_RANGE = (0.02, 0.05)  # m
TURN_RANGE = (math.radians(15.0), math.radians(45.0))


@dataclass
class FaultInjector:
    seed: int
    removal_times: list[float] = field(default_factory=list)  # s of simulated time, ascending
    drop_probability: float = 0.0
    misplaced_tiles: frozenset[int] = frozenset()  # tiles whose first placement lands off
    wrong_type_tiles: frozenset[int] = frozenset()  # tiles whose first placement is of a wrong type
    rng: random.Random = field(init=False)
    landed: set[int] = field(init=False, default_factory=set)  # chosen tiles placed once already

    def __post_init__(self) -> None:
        if not 0.0 <= self.drop_probability <= 1.0:
            raise ValueError("drop_probability must lie in [0, 1]")
        if self.misplaced_tiles & self.wrong_type_tiles:
            raise ValueError("a placement cannot both land off and be of the wrong type")
        self.rng = random.Random(self.seed)
        self.removal_times = sorted(self.removal_times)

    @classmethod
    def scheduled(
        cls, seed: int, removals: int, window: tuple[float, float], drop_probability: float = 0.0
    ) -> FaultInjector:
        """`removals` removal times drawn uniformly in `window` (s)."""
        rng = random.Random(seed * 7919 + 17)
        times = sorted(rng.uniform(*window) for _ in range(removals))
        return cls(seed=seed, removal_times=times, drop_probability=drop_probability)

    def due(self, now: float) -> int:
        """How many removals are due at `now` (they stay due until `removed` is called)."""
        return sum(1 for t in self.removal_times if t <= now)

    def next_removal_after(self, now: float) -> float | None:
        """The time (s) of the first removal not yet due at `now`, if any: the world's clock stops
        there, so a removal happens at its time however far apart a busy host's ticks are."""
        return next((t for t in self.removal_times if t > now), None)

    def choose(self, candidates: list[int]) -> int | None:
        """The tile to remove among `candidates`, or None when there is none."""
        return self.rng.choice(sorted(candidates)) if candidates else None

    def removed(self) -> None:
        """The earliest due removal happened."""
        self.removal_times.pop(0)

    def drops(self) -> bool:
        """Whether the tile being placed now slips from the gripper."""
        return self.drop_probability > 0 and self.rng.random() < self.drop_probability

    def landing(self, structure: Structure, tile_id: int) -> Misplacement | None:
        """How `tile_id`, placed now, really lands: None when as planned (and every time after the first)."""
        if tile_id in self.landed or tile_id not in self.misplaced_tiles | self.wrong_type_tiles:
            return None
        self.landed.add(tile_id)
        draw = random.Random(self.seed * 104729 + tile_id)
        if tile_id in self.wrong_type_tiles:
            other = mistaken_type(structure, structure.tiles[tile_id].type_name)
            return None if other is None else Misplacement(type_name=other)
        if draw.random() < 0.5:
            distance = draw.uniform(*SHIFT_RANGE)
            direction = draw.uniform(0.0, 2.0 * math.pi)
            return Misplacement(shift=(distance * math.cos(direction), distance * math.sin(direction)))
        # a turn by a tile's symmetry leaves it as planned: an octagon turned 40 degrees is 5 off
        largest = min(TURN_RANGE[1], math.pi / turn_symmetry(structure.tiles[tile_id]))
        return Misplacement(turn=draw.choice((-1.0, 1.0)) * draw.uniform(TURN_RANGE[0], largest))


def choose_wrong_tiles(
    seed: int, structure: Structure, misplaced: int, wrong_type: int
) -> tuple[frozenset[int], frozenset[int]]:
    """Which tiles of `structure` land off and which are put down as a tile of the wrong type (only
    tiles whose same-height mix-up fits where they go, whatever lies around; a bigger tile would not
    go down at all); fewer when the structure has too few."""
    rng = random.Random(seed * 7919 + 29)
    mixable = [t for t in structure.tile_ids if _mix_up_fits(structure, t)]
    wrong = rng.sample(mixable, min(wrong_type, len(mixable)))
    rest = sorted(set(structure.tiles) - set(wrong))
    return frozenset(rng.sample(rest, min(misplaced, len(rest)))), frozenset(wrong)


def _mix_up_fits(structure: Structure, tile_id: int) -> bool:
    other = mistaken_type(structure, structure.tiles[tile_id].type_name)
    if other is None:
        return False
    around = set(structure.tiles) - {tile_id} - nx.descendants(structure.precedence, tile_id)
    return PhysicalWorld(structure, present=around).room_for(tile_id, Misplacement(type_name=other))


def mistaken_type(structure: Structure, type_name: str) -> str | None:
    """The type a robot picks by mistake for `type_name`: of the same height, from the cache nearest
    `type_name`'s; None when no other type has its height (or the caches are unknown)."""
    def height(name: str) -> float:
        z = structure.tile_types[name].shape.vertices[:, 2]
        return float(z.max() - z.min())

    home = structure.caches.get(type_name)
    if home is None:
        return None
    same_height = [n for n in structure.tile_types
                   if n != type_name and abs(height(n) - height(type_name)) < 1e-3 and n in structure.caches]
    if not same_height:
        return None
    return min(same_height, key=lambda n: (math.dist(structure.caches[n], home), n))
