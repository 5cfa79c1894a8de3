"""iRobot Create driver: owns the serial port, streams sensors, drives, guards the wheels (no ROS).

Session: Start, Safe or Full mode, then a sensor stream (one frame per 15 ms) that carries
bumpers/wheel drops, odometry inputs, battery and OI mode. The driver

* integrates odometry from distance/angle (Create 1) or wheel encoders (Create 2), by parameter;
* drives with Drive Direct, clamping the body twist to the configured limits and each wheel to
  +-500 mm/s (scaled together, so the curvature is kept);
* stops the wheels when commands stop for ``watchdog_timeout`` (0.2 s);
* stops the wheels on a bump or wheel drop; while a wheel is dropped it refuses to drive, while a
  bumper is pressed it accepts only commands that back away (v <= 0);
* validates every frame's checksum, resynchronises on garbage and counts corrupt frames;
* treats a stream silent for ``stream_timeout`` as a lost robot (off, asleep, wrong baud) and
  reconnects, as it does when the port disappears.
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass, field

from hardware_drivers import create_oi
from hardware_drivers.create_oi import CHARGING_STATES, Hazards, OIMode, PacketId
from hardware_drivers.device_health import EventSink, Level
from hardware_drivers.differential_odometry import (
    CREATE1_WHEELS,
    CREATE2_WHEELS,
    DifferentialOdometry,
    EncoderOdometry,
    WheelGeometry,
    wheel_speeds,
)
from hardware_drivers.planar_pose import Pose2D
from hardware_drivers.serial_link import DeviceNotRespondingError, SerialPort, SupervisedDevice

ODOMETRY_SOURCES = ("distance_angle", "encoders")
MODELS = ("create1", "create2")


@dataclass(frozen=True)
class CreateConfig:
    port: str
    baud: int = 57600
    model: str = "create1"  # create1 | create2 (wheel geometry and stream contents)
    mode: str = "safe"  # safe | full
    odometry: str = "distance_angle"  # distance_angle | encoders (create2 only)
    max_linear: float = 0.3  # m/s, body limit before the per-wheel limit
    max_angular: float = 2.0  # rad/s
    max_wheel_speed: float = 0.5  # m/s, the OI's limit
    watchdog_timeout: float = 0.2  # s without a command before the wheels stop
    stream_timeout: float = 0.5  # s without a valid frame before the robot counts as lost
    connect_timeout: float = 1.0  # s to wait for the first frame after the handshake
    retry_interval: float = 0.5  # s between reconnect attempts
    wheels: WheelGeometry | None = None  # default: the model's geometry

    def validate(self) -> None:
        problems = []
        if self.model not in MODELS:
            problems.append(f"model must be one of {MODELS}, got '{self.model}'")
        if self.mode not in ("safe", "full"):
            problems.append(f"mode must be 'safe' or 'full', got '{self.mode}'")
        if self.odometry not in ODOMETRY_SOURCES:
            problems.append(f"odometry must be one of {ODOMETRY_SOURCES}, got '{self.odometry}'")
        if self.odometry == "encoders" and self.model != "create2":
            problems.append("odometry 'encoders' needs model 'create2' (Create 1 has no encoder packets)")
        for name in ("max_linear", "max_angular", "max_wheel_speed", "watchdog_timeout",
                     "stream_timeout", "connect_timeout", "retry_interval"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                problems.append(f"{name} must be a positive number, got {value}")
        if self.max_wheel_speed > create_oi.MAX_WHEEL_SPEED_MM_S / 1000.0:
            problems.append(f"max_wheel_speed must not exceed 0.5 m/s, got {self.max_wheel_speed}")
        if self.baud <= 0:
            problems.append(f"baud must be positive, got {self.baud}")
        if problems:
            raise ValueError("; ".join(problems))

    @property
    def wheel_geometry(self) -> WheelGeometry:
        if self.wheels is not None:
            return self.wheels
        return CREATE2_WHEELS if self.model == "create2" else CREATE1_WHEELS


@dataclass(frozen=True)
class CreateState:
    """What the base reports, as of `stamp` (time.monotonic())."""

    stamp: float
    pose: Pose2D  # odometry frame
    linear_velocity: float  # m/s, measured
    angular_velocity: float  # rad/s, measured
    hazards: Hazards
    voltage: float  # V
    current: float  # A (negative: discharging)
    temperature: float  # degC
    charge: float  # Ah
    capacity: float  # Ah
    charging_state: str
    oi_mode: OIMode
    commanded: tuple[float, float] = field(default=(0.0, 0.0))  # (right, left) m/s sent last


class CreateDriver(SupervisedDevice):
    device_name = "iRobot Create"

    def __init__(self, config: CreateConfig, on_event: EventSink | None = None) -> None:
        config.validate()
        super().__init__(config.port, config.baud, config.retry_interval, on_event)
        self.config = config
        self.packet_ids = create_oi.CREATE2_STREAM if config.model == "create2" else create_oi.CREATE1_STREAM
        self._lock = threading.Lock()
        self._odometry = DifferentialOdometry()
        self._encoders = EncoderOdometry(config.wheel_geometry)
        self._state: CreateState | None = None
        self._sequence = 0  # number of frames integrated since start (all sessions)
        self._last_command_time = 0.0
        self._commanded = (0, 0)  # (right, left) mm/s last sent
        self._hazards = Hazards(False, False, False, False)
        self._parser = create_oi.StreamParser(self.packet_ids)
        self._frames_before = self._corrupt_before = self._discarded_before = 0  # earlier sessions
        self.health.set_value("port", config.port)
        self.health.set_value("model", config.model)
        self.health.set_value("mode", config.mode)
        self.health.set_value("odometry", config.odometry)

    # ------------------------------------------------------------------ public API
    def drive(self, linear: float, angular: float) -> tuple[float, float]:
        """Command a body twist (m/s, rad/s); returns the (right, left) wheel speeds it commands
        (m/s; nothing reaches the robot while it is disconnected).

        Clamped to max_linear/max_angular and the per-wheel limit; zero while a wheel is dropped;
        forward motion refused while a bumper is pressed. Restarts the watchdog.
        """
        cfg = self.config
        linear = max(-cfg.max_linear, min(cfg.max_linear, linear)) if math.isfinite(linear) else 0.0
        angular = max(-cfg.max_angular, min(cfg.max_angular, angular)) if math.isfinite(angular) else 0.0
        with self._lock:
            hazards = self._hazards
            self._last_command_time = time.monotonic()
        if hazards.wheel_dropped:
            linear = angular = 0.0
        elif hazards.bumped and linear > 0.0:
            linear = angular = 0.0
        right, left = wheel_speeds(linear, angular, cfg.wheel_geometry.wheel_base, cfg.max_wheel_speed)
        self._send_wheels(round(right * 1000.0), round(left * 1000.0))
        return right, left

    def stop_wheels(self) -> None:
        self._send_wheels(0, 0, force=True)

    def state(self) -> tuple[int, CreateState | None]:
        """(sequence number of the latest frame, state); the sequence grows with every frame."""
        with self._lock:
            return self._sequence, self._state

    def reset_odometry(self) -> None:
        with self._lock:
            self._odometry.reset()

    # ------------------------------------------------------------------ internals
    def _send_wheels(self, right_mm_s: int, left_mm_s: int, force: bool = False) -> bool:
        port = self.port
        if port is None or not self.connected:
            return False
        with self._lock:
            unchanged = (right_mm_s, left_mm_s) == self._commanded
        if unchanged and not force and (right_mm_s, left_mm_s) == (0, 0):
            return True  # already stopped: do not flood the line with zeros
        try:
            port.write(create_oi.drive_direct(right_mm_s, left_mm_s))
        except Exception:
            return False
        with self._lock:
            self._commanded = (right_mm_s, left_mm_s)
        return True

    def _handshake(self, port: SerialPort) -> None:
        mode = OIMode.FULL if self.config.mode == "full" else OIMode.SAFE
        port.discard_input()
        port.write(create_oi.start())
        time.sleep(0.02)  # the OI needs a moment after Start before the mode command
        port.write(create_oi.mode_command(mode))
        port.write(create_oi.drive_direct(0, 0))
        port.write(create_oi.stream(self.packet_ids))

    def _session(self, port: SerialPort) -> None:
        self._parser = create_oi.StreamParser(self.packet_ids)
        self._encoders.reset()
        with self._lock:
            self._commanded = (0, 0)
        self._handshake(port)
        deadline = time.monotonic() + self.config.connect_timeout
        first: list[dict[int, int]] = []
        while not first:
            if time.monotonic() > deadline:
                garbled = self._parser.discarded_bytes
                baud = f"the baud rate {self.config.baud} right (Create 1: 57600, Create 2: 115200)?"
                hint = (
                    f"received {garbled} bytes but no valid frame: is {baud}" if garbled
                    else f"is the robot switched on, the cable plugged in, and {baud}"
                )
                self._count_parser()
                raise DeviceNotRespondingError(
                    f"no sensor stream from {self.path} within {self.config.connect_timeout:g} s; {hint}"
                )
            first = self._parser.feed(port.read())
            if self._stopping.is_set():
                return
        self._connected(
            f"connected to the {self.device_name} on {self.path} ({self.config.baud} baud, "
            f"{self.config.mode} mode, {self.config.odometry} odometry)"
        )
        self._apply_frames(first)
        last_frame = time.monotonic()
        while not self._stopping.is_set():
            frames = self._parser.feed(port.read())
            now = time.monotonic()
            if frames:
                last_frame = now
                self._apply_frames(frames)
            elif now - last_frame > self.config.stream_timeout:
                self._count_parser()
                raise DeviceNotRespondingError(
                    f"no valid sensor frame for {self.config.stream_timeout:g} s (robot off or asleep?)"
                )
            self._count_parser()
            self._check_watchdog(now)
        self.stop_wheels()

    def _count_parser(self) -> None:
        self.health.set_counter("frames", self._parser.frames + self._frames_before)
        self.health.set_counter("corrupt_frames", self._parser.corrupt_frames + self._corrupt_before)
        self.health.set_counter("discarded_bytes", self._parser.discarded_bytes + self._discarded_before)

    def _on_disconnect(self) -> None:
        # keep the counters across sessions
        self._frames_before += self._parser.frames
        self._corrupt_before += self._parser.corrupt_frames
        self._discarded_before += self._parser.discarded_bytes
        self._parser = create_oi.StreamParser(self.packet_ids)

    def _check_watchdog(self, now: float) -> None:
        with self._lock:
            moving = self._commanded != (0, 0)
            idle = now - self._last_command_time
        if moving and idle > self.config.watchdog_timeout:
            self._send_wheels(0, 0, force=True)
            self.health.count("watchdog_stops")
            self.health.event(
                Level.OK, f"no velocity command for {self.config.watchdog_timeout:g} s: wheels stopped"
            )

    def _apply_frames(self, frames: list[dict[int, int]]) -> None:
        now = time.monotonic()
        for values in frames:
            hazards = Hazards.from_byte(values[PacketId.BUMPS_WHEEL_DROPS])
            self._handle_hazards(hazards)
            if self.config.odometry == "encoders":
                distance, dyaw = self._encoders.step(values[PacketId.LEFT_ENCODER],
                                                     values[PacketId.RIGHT_ENCODER])
            else:
                distance = values[PacketId.DISTANCE] / 1000.0
                dyaw = math.radians(values[PacketId.ANGLE])
            with self._lock:
                pose = self._odometry.advance(distance, dyaw, now)
                self._sequence += 1
                self._state = CreateState(
                    stamp=now,
                    pose=pose,
                    linear_velocity=self._odometry.linear_velocity,
                    angular_velocity=self._odometry.angular_velocity,
                    hazards=hazards,
                    voltage=values[PacketId.VOLTAGE] / 1000.0,
                    current=values[PacketId.CURRENT] / 1000.0,
                    temperature=float(values[PacketId.TEMPERATURE]),
                    charge=values[PacketId.BATTERY_CHARGE] / 1000.0,
                    capacity=values[PacketId.BATTERY_CAPACITY] / 1000.0,
                    charging_state=CHARGING_STATES.get(values[PacketId.CHARGING_STATE], "unknown"),
                    oi_mode=OIMode(values[PacketId.OI_MODE]) if values[PacketId.OI_MODE] <= 3 else OIMode.OFF,
                    commanded=(self._commanded[0] / 1000.0, self._commanded[1] / 1000.0),
                )
        if self._state is not None:
            state = self._state
            self.health.set_value("battery_voltage", f"{state.voltage:.2f} V")
            self.health.set_value("battery_charge", f"{state.charge:.2f} / {state.capacity:.2f} Ah")
            self.health.set_value("oi_mode", state.oi_mode.name.lower())
            self.health.set_value("hazards", state.hazards.describe())

    def _handle_hazards(self, hazards: Hazards) -> None:
        with self._lock:
            previous, self._hazards = self._hazards, hazards
        new_bump = hazards.bumped and not previous.bumped
        new_drop = hazards.wheel_dropped and not previous.wheel_dropped
        if new_bump or new_drop:
            self._send_wheels(0, 0, force=True)
            self.health.count("hazard_stops")
            self.health.event(Level.ERROR, f"wheels stopped: {hazards.describe()}", set_state=True)
        elif previous != hazards and not (hazards.bumped or hazards.wheel_dropped):
            self.health.event(Level.OK, "bumpers released and wheels down: driving allowed again",
                              set_state=True)
        elif hazards.bumped or hazards.wheel_dropped:
            if previous != hazards:
                self.health.event(Level.ERROR, f"hazard: {hazards.describe()}", set_state=True)
