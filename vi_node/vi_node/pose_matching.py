"""Pair every scan with the overhead pose nearest to it in time (paper section 2.2.1: the overhead
system gives the pose prior of the scan), and with where the other robots were then (the overhead
cameras localize every robot; `robot_mask` leaves their points out)."""

from __future__ import annotations

import bisect
from collections.abc import Iterable

from vi_node.pose_prior import OverheadPose


class PoseBuffer:
    """Overhead poses by time stamp (ns), the most recent `capacity` of them."""

    def __init__(self, capacity: int = 2000, poses: Iterable[tuple[int, OverheadPose]] = ()) -> None:
        self.capacity = capacity
        self._stamps: list[int] = []
        self._poses: list[OverheadPose] = []
        for stamp, pose in poses:
            self.add(stamp, pose)

    def __len__(self) -> int:
        return len(self._stamps)

    def add(self, stamp_ns: int, pose: OverheadPose) -> None:
        index = bisect.bisect_right(self._stamps, stamp_ns)
        self._stamps.insert(index, stamp_ns)
        self._poses.insert(index, pose)
        if len(self._stamps) > self.capacity:
            del self._stamps[0], self._poses[0]

    @property
    def latest(self) -> OverheadPose | None:
        return self._poses[-1] if self._poses else None

    @property
    def latest_stamp(self) -> int | None:
        return self._stamps[-1] if self._stamps else None

    def nearest(self, stamp_ns: int, tolerance_ns: int) -> tuple[OverheadPose, int] | None:
        """The pose nearest to `stamp_ns` and its time difference (ns), if within the tolerance."""
        if not self._stamps:
            return None
        index = bisect.bisect_left(self._stamps, stamp_ns)
        best = min(
            (i for i in (index - 1, index) if 0 <= i < len(self._stamps)),
            key=lambda i: abs(self._stamps[i] - stamp_ns),
        )
        gap = abs(self._stamps[best] - stamp_ns)
        return (self._poses[best], gap) if gap <= tolerance_ns else None


class TeamPoses:
    """The overhead poses of the other robots, one buffer per robot (by name)."""

    def __init__(self, capacity: int = 2000) -> None:
        self.capacity = capacity
        self.buffers: dict[str, PoseBuffer] = {}

    def add(self, robot: str, stamp_ns: int, pose: OverheadPose) -> None:
        self.buffers.setdefault(robot, PoseBuffer(self.capacity)).add(stamp_ns, pose)

    def behind(self, stamp_ns: int, robots: Iterable[str]) -> list[str]:
        """Those of `robots` with no pose as new as `stamp_ns`: their pose of that moment may still be
        on its way (each comes on its own topic, in no order with the scan)."""
        latest = {name: buffer.latest_stamp for name, buffer in self.buffers.items()}
        return sorted(name for name in robots if latest.get(name) is None or latest[name] < stamp_ns)

    def latest(self, robots: list[str]) -> list[OverheadPose]:
        """The latest pose of each of `robots` heard of."""
        buffers = [self.buffers[r] for r in robots if r in self.buffers]
        return [b.latest for b in buffers if b.latest is not None]

    def at(self, stamp_ns: int, tolerance_ns: int) -> list[OverheadPose]:
        """Where each robot was at `stamp_ns`: its pose nearest in time, if within the tolerance."""
        found = (buffer.nearest(stamp_ns, tolerance_ns) for buffer in self.buffers.values())
        return [match[0] for match in found if match is not None]
