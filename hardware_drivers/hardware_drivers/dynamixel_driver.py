"""CrustCrawler arm driver: AX-12 servos on one Dynamixel bus (Protocol 1.0), no ROS.

:class:`DynamixelBus` does transactions: send an instruction, wait for the matching status packet
with a timeout, retry a bounded number of times, never hang ("no status packet" is the most common
field failure); a status packet that does not fit the request (a late reply to an earlier one) is
skipped. :class:`ArmDriver` runs the arm: at connect it pings every joint, writes the servos' CW/CCW
angle limits from the joint limits and enables torque (a joint whose configuration went unanswered
is configured again once it answers: left half done, its servo would never move); then, at a fixed
rate, it sends pending goals (one SYNC_WRITE of goal position and moving speed for all joints, no
status reply) and reads every joint's goal registers and state block (position, speed, load,
voltage, temperature, moving) with the error byte of its status packet. A goal a servo does not
hold was lost on the bus: it is written again, acknowledged, a bounded number of times. Joint
errors (overload, overheating, input voltage...) are reported when they appear and when they
clear; a joint counts as not answering after ``joint_silent_reads`` reads in a row and
``joint_silent_timeout`` without a reply.

Joint angles are the arm's (rad, see ``arm_kinematics``); each joint maps to its servo through
``servo_angle = direction * joint_angle + offset``.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

from hardware_drivers import dynamixel_protocol as dx
from hardware_drivers.device_health import EventSink, Level
from hardware_drivers.dynamixel_protocol import AX12, ErrorBit, Instruction
from hardware_drivers.serial_link import (
    DeviceNotRespondingError,
    SerialPort,
    SupervisedDevice,
)


@dataclass(frozen=True)
class JointConfig:
    name: str
    servo_id: int
    offset: float = 0.0  # rad, servo angle when the joint is at 0
    direction: int = 1  # +1 or -1
    lower: float = -2.6  # rad, joint limits
    upper: float = 2.6
    max_velocity: float = 1.0  # rad/s

    def to_servo(self, angle: float) -> float:
        return self.direction * angle + self.offset

    def from_servo(self, servo_angle: float) -> float:
        return (servo_angle - self.offset) * self.direction

    def problem(self) -> str | None:
        if not 0 <= self.servo_id <= dx.MAX_ID:
            return f"joint {self.name}: servo id {self.servo_id} outside 0..{dx.MAX_ID}"
        if self.direction not in (1, -1):
            return f"joint {self.name}: direction must be 1 or -1"
        if not self.lower < self.upper:
            return f"joint {self.name}: lower limit {self.lower} not below upper limit {self.upper}"
        if not (math.isfinite(self.max_velocity) and self.max_velocity > 0):
            return f"joint {self.name}: max_velocity must be positive"
        for limit in (self.lower, self.upper):
            try:
                dx.radians_to_position(self.to_servo(limit))
            except ValueError as error:
                return f"joint {self.name}: limit {limit:.3f} rad maps outside the servo: {error}"
        return None


@dataclass(frozen=True)
class ArmConfig:
    port: str
    joints: tuple[JointConfig, ...]
    baud: int = 1_000_000
    rate: float = 20.0  # Hz, joint state reads and goal writes
    reply_timeout: float = 0.03  # s per status packet
    retries: int = 3  # attempts per transaction
    retry_interval: float = 0.5  # s between reconnect attempts
    silent_timeout: float = 1.0  # s without any servo answering before the bus counts as lost
    # a joint counts as not answering after this many reads in a row and this long without a reply:
    # a missed read (a busy host, noise on the bus) is tried again next cycle, not a fault that ends
    # a mission; the count matters when unanswered reads stretch the cycles on a slow host
    joint_silent_reads: int = 3
    joint_silent_timeout: float = 0.5  # s
    goal_resends: int = 3  # re-sends of a goal a servo did not take, before reporting it
    goal_tolerance: float = 0.02  # rad, a trajectory point counts as reached this close
    trajectory_wait: float = 2.0  # s a lagging trajectory point is waited for before the next is sent

    def validate(self) -> None:
        problems = [p for p in (j.problem() for j in self.joints) if p]
        names = [j.name for j in self.joints]
        ids = [j.servo_id for j in self.joints]
        if not self.joints:
            problems.append("no joints configured")
        if len(set(names)) != len(names):
            problems.append(f"joint names repeat: {names}")
        if len(set(ids)) != len(ids):
            problems.append(f"servo ids repeat: {ids}")
        for name in ("rate", "reply_timeout", "retry_interval", "silent_timeout", "joint_silent_timeout",
                     "trajectory_wait", "goal_tolerance"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                problems.append(f"{name} must be positive, got {value}")
        if self.retries < 1:
            problems.append(f"retries must be at least 1, got {self.retries}")
        if self.joint_silent_reads < 1:
            problems.append(f"joint_silent_reads must be at least 1, got {self.joint_silent_reads}")
        if self.goal_resends < 0:
            problems.append(f"goal_resends must not be negative, got {self.goal_resends}")
        if problems:
            raise ValueError("; ".join(problems))


@dataclass(frozen=True)
class JointReading:
    name: str
    position: float  # rad, joint angle
    velocity: float  # rad/s
    load: float  # signed fraction of the maximum torque
    voltage: float  # V
    temperature: float  # degC
    moving: bool
    errors: tuple[str, ...]  # error bits of the status packet
    stamp: float  # time.monotonic()


class JointGoalError(ValueError):
    """A goal the arm refuses (unknown joint, outside the joint limits)."""


class ServoSilentError(Exception):
    """One servo did not answer after the bounded retries."""


class DynamixelBus:
    """Instruction/status transactions on one port, with timeouts and bounded retries."""

    def __init__(self, port: SerialPort, reply_timeout: float, retries: int,
                 on_retry: Callable[[int], None] | None = None) -> None:
        self.port = port
        self.reply_timeout = reply_timeout
        self.retries = retries
        self.parser = dx.PacketParser()
        self.failed_attempts = 0  # attempts without a valid status packet
        self.silent_transactions = 0  # transactions that failed every attempt
        self.checksum_retries = 0
        self.stale_replies = 0  # status packets that answered an earlier request
        self._on_retry = on_retry

    def transact(self, servo_id: int, instruction: int, params: bytes = b"",
                 reply_length: int = 0) -> dx.Packet:
        """The servo's status packet (with `reply_length` parameter bytes) for one instruction;
        ServoSilentError after `retries` attempts."""
        packet = dx.instruction_packet(servo_id, instruction, params)
        for attempt in range(1, self.retries + 1):
            reply = self._attempt(servo_id, packet, reply_length)
            if reply is not None:
                return reply
            self.failed_attempts += 1
            if attempt < self.retries and self._on_retry is not None:
                self._on_retry(servo_id)
        self.silent_transactions += 1
        raise ServoSilentError(f"servo {servo_id} gave no valid status packet after {self.retries} tries")

    def _attempt(self, servo_id: int, packet: bytes, reply_length: int) -> dx.Packet | None:
        self.port.discard_input()
        self.parser.reset()
        self.port.write(packet)
        deadline = time.monotonic() + self.reply_timeout
        while True:
            remaining = deadline - time.monotonic()
            # Read at least once more after the deadline: a reply that arrived while this thread
            # was not scheduled (a busy host) is an answer, not a timeout.
            for reply in self.parser.feed(self.port.read(timeout=max(0.0, remaining))):
                if reply.servo_id == servo_id and reply.code & ErrorBit.CHECKSUM:
                    self.checksum_retries += 1  # the servo received a damaged packet
                    return None
                if reply.servo_id != servo_id or len(reply.params) != reply_length:
                    # a late reply to an earlier request: taking it would mix up the answers
                    self.stale_replies += 1
                    continue
                return reply
            if remaining <= 0:
                return None

    def send(self, packet: bytes) -> None:
        """An instruction without a status reply (broadcast, SYNC_WRITE)."""
        self.port.write(packet)

    def ping(self, servo_id: int) -> int:
        return self.transact(servo_id, Instruction.PING).code

    def read(self, servo_id: int, address: int, length: int) -> dx.Packet:
        return self.transact(servo_id, Instruction.READ, bytes([address, length]), reply_length=length)

    def write(self, servo_id: int, address: int, data: bytes) -> int:
        return self.transact(servo_id, Instruction.WRITE, bytes([address]) + bytes(data)).code


Goal = tuple[int, int]  # raw goal position and moving speed of one servo


class ArmDriver(SupervisedDevice):
    device_name = "CrustCrawler arm"

    def __init__(self, config: ArmConfig, on_event: EventSink | None = None) -> None:
        config.validate()
        super().__init__(config.port, config.baud, config.retry_interval, on_event)
        self.config = config
        self.joints = {j.name: j for j in config.joints}
        self._lock = threading.Lock()
        self._readings: dict[str, JointReading] = {}
        self._sequence = 0
        self._pending_goals: dict[str, Goal] = {}  # name -> goal not sent yet
        self._targets: dict[str, float] = {}  # last goal per joint (rad), for reporting
        self._pending_torque: tuple[bool, threading.Event, list[str]] | None = None
        self._errors: dict[str, tuple[str, ...]] = {}
        self._silent: set[str] = set()
        self._bus: DynamixelBus | None = None
        self._corrupt_before = self._failed_before = self._silent_before = 0  # earlier sessions
        # Owned by the session thread:
        self._sent_goals: dict[str, Goal] = {}  # the goal each servo should hold
        self._resends: dict[str, int] = {}  # re-sends of a joint's goal that the servo has not taken yet
        self._unconfigured: set[str] = set()  # joints not configured in this session yet
        self._configure_failing: dict[str, float] = {}  # name -> time of its first failed configuration
        self._last_answer: dict[str, float] = {}
        self._missed_reads: dict[str, int] = {}  # unanswered reads in a row per joint
        self.health.set_value("port", config.port)
        self.health.set_value("joints", ", ".join(f"{j.name}={j.servo_id}" for j in config.joints))

    # ------------------------------------------------------------------ public API
    def check_goal(self, positions: Mapping[str, float]) -> None:
        for name, angle in positions.items():
            joint = self.joints.get(name)
            if joint is None:
                raise JointGoalError(f"unknown joint '{name}' (joints: {', '.join(self.joints)})")
            if not math.isfinite(angle):
                raise JointGoalError(f"goal for joint {name} is not a number")
            if not joint.lower - 1e-9 <= angle <= joint.upper + 1e-9:
                raise JointGoalError(
                    f"goal {angle:.3f} rad for joint {name} is outside its limits "
                    f"[{joint.lower:.3f}, {joint.upper:.3f}] rad"
                )

    def set_goals(self, positions: Mapping[str, float], duration: float | None = None,
                  velocities: Mapping[str, float] | None = None) -> dict[str, float]:
        """Send joints to `positions` (rad). Speeds: reach together in `duration` s, or the given
        `velocities`, never above each joint's max_velocity. Returns the speeds used (rad/s).

        Raises JointGoalError (nothing is sent) for an unknown joint or a goal outside the limits.
        """
        self.check_goal(positions)
        with self._lock:
            current = {n: r.position for n, r in self._readings.items()}
        speeds: dict[str, float] = {}
        for name, angle in positions.items():
            joint = self.joints[name]
            speed = joint.max_velocity
            if velocities and name in velocities and velocities[name] > 0:
                speed = min(speed, velocities[name])
            elif duration and duration > 0 and name in current:
                speed = min(speed, max(abs(angle - current[name]) / duration, 0.02))
            speeds[name] = speed
        with self._lock:
            for name, angle in positions.items():
                joint = self.joints[name]
                self._pending_goals[name] = (
                    dx.radians_to_position(joint.to_servo(angle)), dx.speed_to_moving_speed(speeds[name])
                )
                self._targets[name] = angle
        return speeds

    def set_torque(self, enabled: bool, timeout: float = 1.0) -> tuple[bool, str]:
        """Enable (re-arming servos shut down by an alarm) or disable torque on every joint."""
        if not self.connected:
            return False, f"{self.device_name} is not connected"
        done = threading.Event()
        problems: list[str] = []
        with self._lock:
            self._pending_torque = (enabled, done, problems)
        if not done.wait(timeout):
            return False, "the arm did not apply the torque change in time"
        if problems:
            return False, "; ".join(problems)
        return True, f"torque {'enabled' if enabled else 'disabled'} on {len(self.joints)} joints"

    def readings(self) -> tuple[int, dict[str, JointReading]]:
        with self._lock:
            return self._sequence, dict(self._readings)

    def targets(self) -> dict[str, float]:
        with self._lock:
            return dict(self._targets)

    def joint_errors(self) -> dict[str, tuple[str, ...]]:
        with self._lock:
            return {n: e for n, e in self._errors.items() if e}

    # ------------------------------------------------------------------ session
    def _session(self, port: SerialPort) -> None:
        bus = DynamixelBus(port, self.config.reply_timeout, self.config.retries,
                           on_retry=lambda _id: self.health.count("retries"))
        self._bus = bus
        answering = []
        missing = []
        for joint in self.config.joints:
            try:
                bus.ping(joint.servo_id)
                answering.append(joint)
            except ServoSilentError:
                missing.append(joint)
        if not answering:
            raise DeviceNotRespondingError(
                f"no servo answers a ping on {self.path} (ids {[j.servo_id for j in self.config.joints]}): "
                f"is the arm powered, and the baud rate {self.config.baud} right?"
            )
        start = time.monotonic()
        # every servo is configured in this session, whatever an earlier one did; a servo that was
        # silent at the ping is configured once it answers
        self._sent_goals.clear()
        self._resends.clear()
        self._unconfigured = {j.name for j in self.config.joints}
        self._configure_failing.clear()
        self._last_answer = {j.name: start for j in answering}
        self._missed_reads = {j.name: 0 for j in answering}
        for joint in answering:
            self._configure(bus, joint)
        self._connected(
            f"connected to the {self.device_name} on {self.path}: "
            f"{len(answering)} of {len(self.config.joints)} joints answer"
        )
        with self._lock:
            self._silent = {j.name for j in missing}
        if missing:
            self.health.event(Level.ERROR, "joints not answering ping: " + ", ".join(
                f"{j.name} (id {j.servo_id})" for j in missing))
        period = 1.0 / self.config.rate
        last_answer = time.monotonic()
        next_cycle = time.monotonic()
        while not self._stopping.is_set():
            self._apply_torque(bus)
            self._configure_owed(bus)
            self._apply_goals(bus)
            if self._read_all(bus):
                last_answer = time.monotonic()
            elif time.monotonic() - last_answer > self.config.silent_timeout:
                raise DeviceNotRespondingError(f"no servo answered for {self.config.silent_timeout:g} s")
            self._update_health(bus)
            next_cycle += period
            delay = next_cycle - time.monotonic()
            if delay > 0:
                self._stopping.wait(delay)
            else:
                next_cycle = time.monotonic()

    def _configure(self, bus: DynamixelBus, joint: JointConfig) -> bool:
        """Angle limits, the goal to hold, torque on. A step left unanswered leaves the joint owed
        (configured again once it answers): half configured, its servo would stay limp for good."""
        low, high = sorted(
            dx.radians_to_position(joint.to_servo(limit)) for limit in (joint.lower, joint.upper)
        )
        try:
            bus.write(joint.servo_id, AX12.CW_ANGLE_LIMIT, dx.u16(low) + dx.u16(high))
            goal = self._sent_goals.get(joint.name)
            if goal is None:
                # hold the present position rather than jump to a stale goal when torque comes on
                reply = bus.read(joint.servo_id, AX12.PRESENT_POSITION, 2)
                present = reply.params[0] | reply.params[1] << 8
                bus.write(joint.servo_id, AX12.GOAL_POSITION, dx.u16(min(max(present, low), high)))
            else:  # a goal sent before the servo was configured still stands
                bus.write(joint.servo_id, AX12.GOAL_POSITION, dx.u16(goal[0]) + dx.u16(goal[1]))
            bus.write(joint.servo_id, AX12.TORQUE_ENABLE, b"\x01")
        except ServoSilentError as error:
            self.health.count("configure_failures")
            if joint.name not in self._configure_failing:
                self._configure_failing[joint.name] = time.monotonic()
                self.health.event(Level.WARN, f"joint {joint.name} (id {joint.servo_id}) not configured "
                                  f"({error}); trying again")
            return False
        self._unconfigured.discard(joint.name)
        self._configure_failing.pop(joint.name, None)
        return True

    def _configure_owed(self, bus: DynamixelBus) -> None:
        """Configure the joints still owed it that answered their last read (a silent servo would
        only cost every cycle its retries)."""
        for name in sorted(self._unconfigured):
            joint = self.joints[name]
            if name not in self._silent and name in self._last_answer and self._configure(bus, joint):
                self.health.event(Level.OK, f"joint {name} (id {joint.servo_id}) configured, torque on")

    def _apply_torque(self, bus: DynamixelBus) -> None:
        with self._lock:
            request, self._pending_torque = self._pending_torque, None
        if request is None:
            return
        enabled, done, problems = request
        for joint in self.config.joints:
            try:
                if enabled:
                    max_torque = bus.read(joint.servo_id, AX12.MAX_TORQUE, 2).params
                    bus.write(joint.servo_id, AX12.TORQUE_LIMIT, max_torque)
                    # the present position out of the joint block: a reply of a length that no other
                    # request here has (Max Torque is 2 bytes too), so a late reply cannot pass for it
                    block = bus.read(joint.servo_id, dx.JOINT_BLOCK_START, dx.JOINT_BLOCK_LENGTH).params
                    present = block[AX12.PRESENT_POSITION - dx.JOINT_BLOCK_START :][:2]
                    bus.write(joint.servo_id, AX12.GOAL_POSITION, present)
                    self._sent_goals.pop(joint.name, None)  # re-armed where it stands
                bus.write(joint.servo_id, AX12.TORQUE_ENABLE, b"\x01" if enabled else b"\x00")
                check = bus.read(joint.servo_id, AX12.TORQUE_ENABLE, 1)
                if bool(check.params[0]) != enabled:
                    errors = ", ".join(dx.describe_errors(check.code)) or "unknown reason"
                    state = "off" if enabled else "on"
                    problems.append(f"joint {joint.name} keeps torque {state} ({errors})")
            except ServoSilentError as error:
                problems.append(f"joint {joint.name}: {error}")
        self.health.event(Level.OK if not problems else Level.ERROR,
                          f"torque {'enabled' if enabled else 'disabled'}"
                          + (f" with problems: {'; '.join(problems)}" if problems else ""))
        done.set()

    def _apply_goals(self, bus: DynamixelBus) -> None:
        with self._lock:
            goals, self._pending_goals = self._pending_goals, {}
        if not goals:
            return
        blocks = {
            self.joints[name].servo_id: dx.u16(position) + dx.u16(speed)
            for name, (position, speed) in goals.items()
        }
        # no status packet comes back: the goal registers read each cycle tell whether it arrived
        bus.send(dx.sync_write(AX12.GOAL_POSITION, blocks))
        self._sent_goals.update(goals)
        for name in goals:
            self._resends.pop(name, None)
        self.health.count("goals_sent")

    def _read_all(self, bus: DynamixelBus) -> bool:
        """Read every joint once; True when at least one answered."""
        any_answer = False
        now = time.monotonic()
        readings: dict[str, JointReading] = {}
        missed: dict[str, Goal] = {}
        errors: dict[str, tuple[str, ...]] = {}
        for joint in self.config.joints:
            try:
                reply = bus.read(joint.servo_id, dx.JOINT_BLOCK_START, dx.JOINT_BLOCK_LENGTH)
            except ServoSilentError:
                self._missed_reads[joint.name] = self._missed_reads.get(joint.name, 0) + 1
                continue
            any_answer = True
            self._last_answer[joint.name] = now
            self._missed_reads[joint.name] = 0
            held, state = dx.decode_joint_block(reply.params)
            sent = self._sent_goals.get(joint.name)
            if sent is not None and (held.position, held.moving_speed) != sent:
                missed[joint.name] = sent
            elif sent is not None:
                self._resends.pop(joint.name, None)
            joint_errors = tuple(dx.describe_errors(reply.code))
            errors[joint.name] = joint_errors
            readings[joint.name] = JointReading(
                name=joint.name,
                position=joint.from_servo(state.position),
                velocity=state.velocity * joint.direction,
                load=state.load * joint.direction,
                voltage=state.voltage,
                temperature=state.temperature,
                moving=state.moving,
                errors=joint_errors,
                stamp=now,
            )
        silent = {name for name in self.joints if self._is_silent(name, now)}
        self._report_changes(silent, errors)
        with self._lock:
            self._readings.update(readings)
            for name in silent:
                self._readings.pop(name, None)
            if readings:
                self._sequence += 1
        self._resend_missed_goals(bus, missed)
        return any_answer

    def _is_silent(self, name: str, now: float) -> bool:
        if name not in self._last_answer:
            return True  # not heard from in this session
        return joint_went_silent(self._missed_reads[name], now - self._last_answer[name], self.config)

    def _resend_missed_goals(self, bus: DynamixelBus, missed: Mapping[str, Goal]) -> None:
        """Write again, with a status reply, the goals the servos do not hold: a SYNC_WRITE that a
        servo did not receive (noise on the bus) would otherwise leave the joint where it is."""
        with self._lock:
            superseded = set(self._pending_goals)
        for name, (position, speed) in missed.items():
            if name in superseded:
                continue  # a newer goal goes out next cycle; re-sending the old one would undo it
            joint = self.joints[name]
            resends = self._resends.get(name, 0)
            if resends == self.config.goal_resends:
                self._resends[name] = resends + 1
                self.health.event(Level.ERROR, f"joint {name} (id {joint.servo_id}) does not take its goal "
                                  f"(position {position}) after {resends} re-sends")
            if resends >= self.config.goal_resends:
                continue
            self._resends[name] = resends + 1
            self.health.count("goals_resent")
            self.health.event(Level.WARN, f"joint {name} (id {joint.servo_id}) missed its goal "
                              f"(position {position}); sending it again")
            try:
                bus.write(joint.servo_id, AX12.GOAL_POSITION, dx.u16(position) + dx.u16(speed))
            except ServoSilentError:
                pass  # the next read shows whether it arrived; if not, it is sent again

    def _report_changes(self, silent: set[str], errors: dict[str, tuple[str, ...]]) -> None:
        with self._lock:
            old_silent, old_errors = self._silent, self._errors
            self._silent = silent
            self._errors = {**{n: e for n, e in old_errors.items() if n in silent}, **errors}
        for name in sorted(silent - old_silent):
            self.health.count("joint_silences")
            tries = f"{self.config.retries} tries of {self.config.reply_timeout * 1000:.0f} ms per read"
            unanswered = f"{self.config.joint_silent_reads} reads in a row over {self.config.joint_silent_timeout:g} s"
            self.health.event(Level.ERROR, f"joint {name} (id {self.joints[name].servo_id}) stopped "
                              f"answering ({unanswered}, {tries})")
        for name in sorted(old_silent - silent):
            self.health.event(Level.OK, f"joint {name} (id {self.joints[name].servo_id}) answers again")
        for name, joint_errors in errors.items():
            before = old_errors.get(name, ())
            if joint_errors and joint_errors != before:
                self.health.count("joint_errors")
                self.health.event(Level.ERROR, f"joint {name} (id {self.joints[name].servo_id}) reports: "
                                  f"{', '.join(joint_errors)}")
            elif before and not joint_errors:
                self.health.event(Level.OK, f"joint {name} (id {self.joints[name].servo_id}): error cleared")

    def _update_health(self, bus: DynamixelBus) -> None:
        self.health.set_counter("failed_attempts", bus.failed_attempts + self._failed_before)
        self.health.set_counter("silent_transactions", bus.silent_transactions + self._silent_before)
        self.health.set_counter("corrupt_packets", bus.parser.corrupt_packets + self._corrupt_before)
        self.health.set_counter("checksum_errors_at_servo", bus.checksum_retries)
        self.health.set_counter("stale_replies", bus.stale_replies)
        now = time.monotonic()
        with self._lock:
            silent = sorted(self._silent)
            errors = {n: e for n, e in self._errors.items() if e}
            readings = dict(self._readings)
        # a joint whose configuration keeps failing cannot move: a fault, once it lasts
        limp = sorted(n for n, since in self._configure_failing.items()
                      if n not in silent and now - since > self.config.joint_silent_timeout)
        problems = [f"{n}: not answering" for n in silent]
        problems += [f"{n}: not configured (torque off)" for n in limp]
        problems += [f"{n}: {', '.join(e)}" for n, e in sorted(errors.items())]
        for name, reading in readings.items():
            self.health.set_value(f"{name}", f"{reading.position:+.3f} rad, {reading.temperature:.0f} C, "
                                  f"{reading.voltage:.1f} V, load {reading.load:+.2f}")
        if problems:
            self.health.set_state(Level.ERROR, "joint faults: " + "; ".join(problems))
        else:
            self.health.set_state(Level.OK, f"{len(readings)} joints answering, no errors")

    def _on_disconnect(self) -> None:
        bus, self._bus = self._bus, None
        if bus is not None:
            self._corrupt_before += bus.parser.corrupt_packets
            self._failed_before += bus.failed_attempts
            self._silent_before += bus.silent_transactions
        with self._lock:
            self._readings.clear()
            pending, self._pending_torque = self._pending_torque, None
        if pending is not None:
            pending[2].append("the arm disconnected")
            pending[1].set()


def joint_went_silent(missed_reads: int, since_answer: float, config: ArmConfig) -> bool:
    """Whether a joint with `missed_reads` unanswered reads in a row, `since_answer` s after its last
    reply, counts as not answering. Both must hold: on a slow host a few unanswered reads stretch a
    cycle past the time limit, and at a high rate a few reads in a row take little time."""
    return missed_reads >= config.joint_silent_reads and since_answer > config.joint_silent_timeout


def joint_configs(names: Sequence[str], ids: Sequence[int], offsets: Sequence[float],
                  directions: Sequence[int], lower: Sequence[float], upper: Sequence[float],
                  max_velocity: Sequence[float]) -> tuple[JointConfig, ...]:
    """Joint configurations from parallel lists (the node's parameters); ValueError on bad lengths."""
    lists = {"servo_ids": ids, "joint_offsets": offsets, "joint_directions": directions,
             "joint_lower_limits": lower, "joint_upper_limits": upper, "joint_max_velocities": max_velocity}
    bad = [f"{k} has {len(v)}" for k, v in lists.items() if len(v) != len(names)]
    if bad:
        raise ValueError(f"{len(names)} joint names but " + ", ".join(bad))
    return tuple(
        JointConfig(n, int(i), float(o), int(d), float(lo), float(hi), float(v))
        for n, i, o, d, lo, hi, v in zip(names, ids, offsets, directions, lower, upper, max_velocity,
                                         strict=True)
    )
