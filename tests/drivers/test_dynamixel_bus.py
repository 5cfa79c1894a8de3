"""DynamixelBus transactions against a scripted port: which status packet answers which request."""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable

from hardware_drivers import dynamixel_protocol as dx
from hardware_drivers.dynamixel_driver import DynamixelBus

REPLY_TIMEOUT = 0.03


class ScriptedPort:
    """Each write makes `answer(packet)` queue the chunks that arrive for the driver to read."""

    def __init__(self, answer: Callable[[bytes], list[bytes]], late_by: float = 0.0) -> None:
        self.answer = answer
        self.late_by = late_by  # the reading thread first wakes this long after its deadline
        self.incoming: deque[bytes] = deque()
        self.written: list[bytes] = []
        self._late_once = False

    def discard_input(self) -> None:
        self.incoming.clear()

    def write(self, data: bytes) -> None:
        self.written.append(data)
        self.incoming.extend(self.answer(data))
        self._late_once = self.late_by > 0

    def read(self, timeout: float | None = None) -> bytes:
        if self._late_once:  # descheduled: the reply came in while the thread was not running
            self._late_once = False
            time.sleep(self.late_by)
            return b""
        if self.incoming:
            return self.incoming.popleft()
        time.sleep(timeout or 0.0)
        return b""


def joint_block(servo_id: int) -> bytes:
    return dx.status_packet(servo_id, 0, bytes(range(dx.JOINT_BLOCK_LENGTH)))


def test_a_late_reply_to_an_earlier_request_is_not_taken_for_the_answer() -> None:
    # the WRITE status of an earlier request, still on its way, arrives first
    port = ScriptedPort(lambda packet: [dx.status_packet(3, 0), joint_block(3)])
    bus = DynamixelBus(port, REPLY_TIMEOUT, retries=3)  # type: ignore[arg-type]
    reply = bus.read(3, dx.JOINT_BLOCK_START, dx.JOINT_BLOCK_LENGTH)
    assert reply.params == bytes(range(dx.JOINT_BLOCK_LENGTH))
    assert bus.stale_replies == 1
    assert bus.failed_attempts == 0


def test_a_reply_that_came_while_the_thread_was_late_is_no_timeout() -> None:
    port = ScriptedPort(lambda packet: [joint_block(3)], late_by=2 * REPLY_TIMEOUT)
    bus = DynamixelBus(port, REPLY_TIMEOUT, retries=3)  # type: ignore[arg-type]
    reply = bus.read(3, dx.JOINT_BLOCK_START, dx.JOINT_BLOCK_LENGTH)
    assert len(reply.params) == dx.JOINT_BLOCK_LENGTH
    assert bus.failed_attempts == 0
    assert len(port.written) == 1  # answered at the first attempt, not re-sent
