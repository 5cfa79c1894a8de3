"""Alarms on simulated time: what a simulated robot's body waits for while a phase of its work runs.

The body learns the time from `/clock`; each message wakes the alarms that are due, in the order
they are due (ties in the order they were set), as the world's own loop woke its sleepers when
it was one process.
"""

from __future__ import annotations

import heapq
import itertools
from collections.abc import Callable


class Alarms:
    def __init__(self) -> None:
        self._heap: list[tuple[float, int, Callable[[], None]]] = []
        self._order = itertools.count()

    def set(self, at: float, wake: Callable[[], None]) -> None:
        """Call `wake` once simulated time reaches `at` (in the unit `due` is given)."""
        heapq.heappush(self._heap, (at, next(self._order), wake))

    def due(self, now: float) -> list[Callable[[], None]]:
        """The alarms due at `now`, taken off the list; the caller calls them."""
        woken = []
        while self._heap and self._heap[0][0] <= now:
            woken.append(heapq.heappop(self._heap)[2])
        return woken

    def __len__(self) -> int:
        return len(self._heap)
