"""Fault injection for the simulated testbed (paper section 3.2: "one or more random assembly tiles
were removed at different parts of the assembly process").

A seeded schedule of removal times per trial, and an optional chance that a tile slips from the
gripper during a placement (the placement then fails). The tile removed at each time is drawn
from the tiles that can be removed then (placed, nothing on top), with the same seeded generator,
so a trial is reproducible from its seed.
"""

from __future__ import annotations

import random
from dataclasses import dataclass, field


@dataclass
class FaultInjector:
    seed: int
    removal_times: list[float] = field(default_factory=list)  # s of simulated time, ascending
    drop_probability: float = 0.0
    rng: random.Random = field(init=False)

    def __post_init__(self) -> None:
        if not 0.0 <= self.drop_probability <= 1.0:
            raise ValueError("drop_probability must lie in [0, 1]")
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

    def choose(self, candidates: list[int]) -> int | None:
        """The tile to remove among `candidates`, or None when there is none."""
        return self.rng.choice(sorted(candidates)) if candidates else None

    def removed(self) -> None:
        """The earliest due removal happened."""
        self.removal_times.pop(0)

    def drops(self) -> bool:
        """Whether the tile being placed now slips from the gripper."""
        return self.drop_probability > 0 and self.rng.random() < self.drop_probability
