"""One goal at a time for a robot's action server, without wedging on a goal that never starts.

An action server that accepts a goal has not yet told its client so: the goal response can still
be lost (over a lossy link, or when the server has not yet discovered the client's response
reader, rclpy logs "Failed to send goal response" and never executes the goal). A server that
marked itself busy on acceptance would then refuse every later goal for ever. The slot is
therefore only *reserved* on acceptance; the reservation lapses when the goal has not started
within ``start_grace`` seconds, and a goal that starts while another runs is refused at start.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable


class GoalSlot:
    """Accept, start and finish one goal at a time (thread-safe)."""

    def __init__(self, start_grace: float = 2.0, clock: Callable[[], float] = time.monotonic) -> None:
        self.start_grace = start_grace
        self._clock = clock
        self._lock = threading.Lock()
        self._reserved_at: float | None = None
        self._running = False

    def reserve(self) -> bool:
        """True when a new goal may be accepted: none runs, none accepted in the last ``start_grace``."""
        with self._lock:
            now = self._clock()
            pending = self._reserved_at is not None and now - self._reserved_at < self.start_grace
            if self._running or pending:
                return False
            self._reserved_at = now
            return True

    def start(self) -> bool:
        """Called when an accepted goal begins executing; False when another goal already runs."""
        with self._lock:
            if self._running:
                return False
            self._running = True
            self._reserved_at = None
            return True

    def finish(self) -> None:
        with self._lock:
            self._running = False

    @property
    def busy(self) -> bool:
        with self._lock:
            return self._running
