"""The simulator-internal interface between `sim_world` and the robots' simulated bodies, and what
the three nodes share on the ROS side (simulated time, the world's services).

Real robots never use it; it stands for the physics the real robots would meet. Names and QoS (the
profiles of `tiling_ros.qos`):

| name | type | from -> to | QoS |
|---|---|---|---|
| `/clock` | rosgraph_msgs/Clock | world -> all | reliable, depth 1000 (bodies read every tick) |
| `/sim/place` | SimPlace.srv | `sim_robot` -> world | service: each placement step, atomically |
| `/sim/snapshot` | SimSnapshot.srv | `sim_vi` -> world | service: tiles, robots, stamp; may hold the clock |
| `/sim/motion` | SimMotion.msg | bodies -> world | reliable, transient local, depth 10: where a base stands |
| `/sim/scan_progress` | SimScanProgress.msg | `sim_vi` -> world | reliable, transient local, depth 20: a scan's fate |
| `/sim/events` | std_msgs/String (JSON) | world -> runner | reliable, transient local, depth 1000 |
| `/sim/start` | std_msgs/Empty | runner -> world | reliable, transient local, depth 1000 |

Everything heavy stays on the robot that makes it: the Kinect's point cloud is rendered by the VI
robot's body from a snapshot of a few hundred bytes and published on its own host.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.task import Future
from rosgraph_msgs.msg import Clock as ClockMsg

from tiling_ros.qos import CLOCK
from tiling_ros.stamps import stamp_to_nanoseconds
from tiling_sim.alarms import Alarms

PLACE = "/sim/place"
SNAPSHOT = "/sim/snapshot"
MOTION = "/sim/motion"
SCAN_PROGRESS = "/sim/scan_progress"
EVENTS = "/sim/events"
START = "/sim/start"

VI_SETTLE = 0.2  # s of simulated time a VI robot's base settles after an arrival before its camera's frame
WORLD_PATIENCE = 30.0  # s of wall time a body waits for the world to answer before giving up


class SimTime:
    """Simulated time as `/clock` tells a body, and alarms on it.

    Every tick is read, in order (reliable, a queue of `tiling_ros.qos.CLOCK_DEPTH`): an alarm wakes at
    the first tick at or after its time, also when the body's process runs late, and its future holds
    that tick's time.
    A body that starts its next phase from that time, not from the latest tick it has heard of,
    keeps the timeline the world had when it was one process, however long messages take.
    """

    def __init__(self, node: Node, on_tick: Callable[[], None] | None = None) -> None:
        self.now = 0.0  # s, the latest /clock
        self._now_ns = 0
        self._alarms = Alarms()  # on whole nanoseconds, as /clock tells them
        self._on_tick = on_tick
        node.create_subscription(ClockMsg, "/clock", self._on_clock, CLOCK)

    def _on_clock(self, msg: ClockMsg) -> None:
        self._now_ns = max(self._now_ns, stamp_to_nanoseconds(msg.clock))
        self.now = self._now_ns * 1e-9
        for wake in self._alarms.due(self._now_ns):
            wake()
        if self._on_tick is not None:
            self._on_tick()

    def until(self, at: float) -> Future:
        """A future done once simulated time reaches `at` (s); its result: the time it woke at."""
        future = Future()
        # compared as /clock stamps: the world holds its clock at exactly this stamp (body_hold)
        self._alarms.set(round(at * 1e9), lambda: future.done() or future.set_result(self.now))
        return future


class WorldClient:
    """A body's client of one of the world's services that waits until the world answers.

    A body serves its robot's action from its start, so that the team's clients discover it early;
    the world's service may be found a little later (discovery takes long on a loaded host). A call
    therefore waits for the service on the wall clock, and a call the world does not answer within
    `WORLD_PATIENCE` s gives None, so a robot whose world is gone fails its goal instead of hanging.
    """

    def __init__(self, node: Node, service_type: Any, name: str) -> None:
        self.client = node.create_client(service_type, name)
        self._until_ready: list[tuple[float, Future]] = []  # (since, future): True once the world answers
        self._answers: list[tuple[float, Future]] = []  # (since, the call's future)
        # a wake of an rclpy process costs about 1 ms of CPU: checking 4 times a second is plenty for 30 s
        node.create_timer(0.25, self._check, clock=Clock(clock_type=ClockType.STEADY_TIME))

    def ready(self) -> bool:
        return self.client.service_is_ready()

    async def call(self, request: Any) -> Any | None:
        """The world's response, or None when it does not answer in time."""
        if not self.ready():
            reached = Future()
            self._until_ready.append((time.monotonic(), reached))
            if not await reached:
                return None
        answer = self.client.call_async(request)
        self._answers.append((time.monotonic(), answer))
        return await answer

    def _check(self) -> None:
        now, ready = time.monotonic(), self.ready()
        for since, future in self._until_ready:
            if not future.done() and (ready or now - since > WORLD_PATIENCE):
                future.set_result(ready)
        for since, future in self._answers:
            if now - since > WORLD_PATIENCE:
                future.cancel()  # its awaiter gets None; the client forgets the request
        self._until_ready = [(t, f) for t, f in self._until_ready if not f.done()]
        self._answers = [(t, f) for t, f in self._answers if not (f.done() or f.cancelled())]
