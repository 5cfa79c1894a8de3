"""iRobot Create emulator on a pseudo-terminal (Open Interface), for tests and trying the nodes.

    ros2 run hardware_drivers create_emulator --port /tmp/m3/create [--model create2 --baud 115200]
        [--pose-file /tmp/m3/pose] [--start-pose X,Y,YAW]

Speaks the OI as the robot does: Start (Passive), Safe/Full, Drive and Drive Direct (ignored in
Passive mode, as on the robot), Stream (a frame every 15 ms with a valid checksum), Pause/Resume,
Sensors and Query List. It integrates the wheel speeds into a true pose (exact arcs), reports
distance (mm) and angle (degrees) since the previous frame carrying the sub-unit remainder over,
as the robot's firmware does, and Create 2 encoder counts that wrap at 65535. In Safe mode a wheel
drop stops the motors and drops to Passive mode, as on the robot.

Control lines on stdin: ``bump left|right|both|none``, ``drop left|right|both|none``,
``corrupt N`` (next N frames with a bad checksum), ``partial`` (next frame cut short),
``garbage N``, ``silence S``, ``unplug S`` (0: until ``plug``), ``plug``, ``pose``, ``quit``.
Events on stdout: ``ready PATH``, ``mode NAME``, ``drive RIGHT LEFT t=T`` (mm/s, monotonic time),
``pose X Y YAW``.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time

from hardware_drivers import create_oi
from hardware_drivers.create_oi import Hazards, OIMode, Opcode, PacketId
from hardware_drivers.differential_odometry import CREATE1_WHEELS, CREATE2_WHEELS
from hardware_drivers.emulators.pty_device import EmulatorApp, common_arguments, run_emulator

STREAM_PERIOD = 0.015
POSE_FILE_PERIOD = 0.05
ENCODER_START = 65300  # close to the wrap so that tests see it


class CreateEmulator(EmulatorApp):
    supports_partial = True
    def __init__(self, link: str, baud: int, model: str, start_pose: tuple[float, float, float],
                 pose_file: str | None, seed: int) -> None:
        super().__init__(link, baud, seed)
        self.model = model
        self.wheels = CREATE2_WHEELS if model == "create2" else CREATE1_WHEELS
        self.x, self.y, self.yaw = start_pose
        self.pose_file = pose_file
        self.hazards = Hazards(False, False, False, False)
        self._input = bytearray()
        self._power_up()
        self._last_motion = time.monotonic()
        self._next_frame = 0.0
        self._next_pose_write = 0.0
        self.write_pose_file()

    def _power_up(self) -> None:
        self.mode = OIMode.OFF
        self.right = self.left = 0  # mm/s
        self.stream_ids: tuple[int, ...] = ()
        self.streaming = False
        self.distance_mm = 0.0  # not yet reported
        self.angle_deg = 0.0
        self.left_ticks = float(ENCODER_START)
        self.right_ticks = float(ENCODER_START)
        self.charge = 2500  # mAh
        self._input = bytearray()

    def on_plugged(self) -> None:
        self._power_up()

    # ------------------------------------------------------------------ motion
    def integrate(self, now: float) -> None:
        dt = now - self._last_motion
        self._last_motion = now
        if dt <= 0:
            return
        right, left = self.right / 1000.0, self.left / 1000.0
        d_right, d_left = right * dt, left * dt
        distance = (d_right + d_left) / 2.0
        dyaw = (d_right - d_left) / self.wheels.wheel_base
        if abs(dyaw) < 1e-12:
            self.x += distance * math.cos(self.yaw)
            self.y += distance * math.sin(self.yaw)
        else:
            radius = distance / dyaw
            self.x += radius * (math.sin(self.yaw + dyaw) - math.sin(self.yaw))
            self.y -= radius * (math.cos(self.yaw + dyaw) - math.cos(self.yaw))
        self.yaw = math.atan2(math.sin(self.yaw + dyaw), math.cos(self.yaw + dyaw))
        self.distance_mm += distance * 1000.0
        self.angle_deg += math.degrees(dyaw)
        self.left_ticks += d_left / self.wheels.metres_per_tick
        self.right_ticks += d_right / self.wheels.metres_per_tick

    def set_wheels(self, right: int, left: int) -> None:
        if (right, left) != (self.right, self.left):
            self.integrate(time.monotonic())
            self.right, self.left = right, left
            self.emit(f"drive {right} {left} t={time.monotonic():.6f}")

    # ------------------------------------------------------------------ sensors
    def sensor_values(self, ids: tuple[int, ...]) -> dict[int, int]:
        values: dict[int, int] = {}
        for packet_id in ids:
            if packet_id == PacketId.DISTANCE:
                reported = round(self.distance_mm)
                self.distance_mm -= reported
                values[packet_id] = max(-32768, min(32767, reported))
            elif packet_id == PacketId.ANGLE:
                reported = round(self.angle_deg)
                self.angle_deg -= reported
                values[packet_id] = max(-32768, min(32767, reported))
            elif packet_id == PacketId.BUMPS_WHEEL_DROPS:
                values[packet_id] = self.hazards.to_byte()
            elif packet_id == PacketId.CHARGING_STATE:
                values[packet_id] = 0
            elif packet_id == PacketId.VOLTAGE:
                values[packet_id] = 15800
            elif packet_id == PacketId.CURRENT:
                values[packet_id] = -200 - (abs(self.right) + abs(self.left))
            elif packet_id == PacketId.TEMPERATURE:
                values[packet_id] = 27
            elif packet_id == PacketId.BATTERY_CHARGE:
                values[packet_id] = self.charge
            elif packet_id == PacketId.BATTERY_CAPACITY:
                values[packet_id] = 3000
            elif packet_id == PacketId.OI_MODE:
                values[packet_id] = int(self.mode)
            elif packet_id == PacketId.LEFT_ENCODER:
                values[packet_id] = math.floor(self.left_ticks) % 65536
            elif packet_id == PacketId.RIGHT_ENCODER:
                values[packet_id] = math.floor(self.right_ticks) % 65536
        return values

    def send_frame(self) -> None:
        frame = bytearray(create_oi.stream_frame(self.sensor_values(self.stream_ids)))
        if self.take_corruption():
            frame[-1] = (frame[-1] + 1) & 0xFF
        if self.take_partial():
            frame = frame[: len(frame) // 2]
        self.send(bytes(frame))

    # ------------------------------------------------------------------ commands from the driver
    def on_bytes(self, data: bytes, now: float) -> None:
        self._input += data
        while self._input:
            try:
                length = create_oi.command_length(bytes(self._input))
            except ValueError:
                del self._input[:1]  # not an opcode: the robot ignores it
                continue
            if length is None or len(self._input) < length:
                return
            command = bytes(self._input[:length])
            del self._input[:length]
            self.execute(command, now)

    def execute(self, command: bytes, now: float) -> None:
        opcode = command[0]
        if self.mode == OIMode.OFF and opcode != Opcode.START:
            return  # the OI listens only for Start
        if opcode == Opcode.START:
            self._set_mode(OIMode.PASSIVE)
        elif opcode == Opcode.SAFE:
            self._set_mode(OIMode.SAFE)
        elif opcode == Opcode.FULL:
            self._set_mode(OIMode.FULL)
        elif opcode in (Opcode.STOP, Opcode.RESET):
            self.set_wheels(0, 0)
            self.streaming = False
            self._set_mode(OIMode.OFF)
        elif opcode == Opcode.DRIVE_DIRECT:
            if self.mode in (OIMode.SAFE, OIMode.FULL):
                right = int.from_bytes(command[1:3], "big", signed=True)
                left = int.from_bytes(command[3:5], "big", signed=True)
                clamp = create_oi.MAX_WHEEL_SPEED_MM_S
                if self.mode == OIMode.SAFE and self.hazards.wheel_dropped:
                    right = left = 0
                self.set_wheels(max(-clamp, min(clamp, right)), max(-clamp, min(clamp, left)))
        elif opcode == Opcode.DRIVE:
            if self.mode in (OIMode.SAFE, OIMode.FULL):
                velocity = int.from_bytes(command[1:3], "big", signed=True)
                radius = int.from_bytes(command[3:5], "big", signed=True)
                self.set_wheels(*self._drive_to_wheels(velocity, radius))
        elif opcode == Opcode.STREAM:
            ids = tuple(command[2:])
            if all(i in create_oi.SENSOR_PACKETS for i in ids):
                self.stream_ids = ids
                self.streaming = bool(ids)
                self._next_frame = now
                self.emit(f"stream {' '.join(str(i) for i in ids)}")
        elif opcode == Opcode.PAUSE_RESUME_STREAM:
            self.streaming = bool(command[1]) and bool(self.stream_ids)
        elif opcode == Opcode.SENSORS:
            if command[1] in create_oi.SENSOR_PACKETS:
                self.integrate(now)
                self.send(create_oi.encode_sensor_values(self.sensor_values((command[1],)))[1:])
        elif opcode == Opcode.QUERY_LIST:
            ids = tuple(i for i in command[2:] if i in create_oi.SENSOR_PACKETS)
            self.integrate(now)
            values = self.sensor_values(ids)
            self.send(b"".join(create_oi.encode_sensor_values({i: v})[1:] for i, v in values.items()))

    def _drive_to_wheels(self, velocity: int, radius: int) -> tuple[int, int]:
        if radius in (32767, -32768):
            return velocity, velocity
        half = self.wheels.wheel_base * 1000.0 / 2.0
        if radius == 1:
            return velocity, -velocity
        if radius == -1:
            return -velocity, velocity
        return round(velocity * (radius + half) / radius), round(velocity * (radius - half) / radius)

    def _set_mode(self, mode: OIMode) -> None:
        if mode != self.mode:
            self.mode = mode
            if mode in (OIMode.PASSIVE, OIMode.OFF):
                self.set_wheels(0, 0)
            self.emit(f"mode {mode.name.lower()}")

    # ------------------------------------------------------------------ periodic work and faults
    def tick(self, now: float) -> None:
        self.integrate(now)
        if self.streaming and self.device.plugged and now >= self._next_frame:
            self._next_frame = max(self._next_frame + STREAM_PERIOD, now - STREAM_PERIOD)
            if now >= self.silent_until:
                self.send_frame()
        if self.pose_file and now >= self._next_pose_write:
            self._next_pose_write = now + POSE_FILE_PERIOD
            self.write_pose_file()

    def write_pose_file(self) -> None:
        if not self.pose_file:
            return
        temporary = f"{self.pose_file}.tmp"
        with open(temporary, "w") as handle:
            handle.write(f"{self.x:.6f} {self.y:.6f} {self.yaw:.6f} {time.monotonic():.6f}\n")
        os.replace(temporary, self.pose_file)

    def command(self, words: list[str], now: float) -> bool:
        verb = words[0]
        if verb in ("bump", "drop"):
            side = words[1] if len(words) > 1 else "both"
            if side not in ("left", "right", "both", "none"):
                raise ValueError("side must be left, right, both or none")
            left, right = side in ("left", "both"), side in ("right", "both")
            if verb == "bump":
                self.hazards = Hazards(right, left, self.hazards.drop_right, self.hazards.drop_left)
            else:
                self.hazards = Hazards(self.hazards.bump_right, self.hazards.bump_left, right, left)
                if self.hazards.wheel_dropped and self.mode == OIMode.SAFE:
                    self._set_mode(OIMode.PASSIVE)  # Safe mode's reaction to a wheel drop
            self.emit(f"{verb} {side}")
        elif verb == "pose":
            self.integrate(now)
            self.emit(f"pose {self.x:.6f} {self.y:.6f} {self.yaw:.6f}")
        else:
            return False
        return True


def _pose(text: str) -> tuple[float, float, float]:
    parts = [float(v) for v in text.split(",")]
    if len(parts) != 3:
        raise argparse.ArgumentTypeError("expected X,Y,YAW")
    return parts[0], parts[1], parts[2]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="create_emulator", description=__doc__.split("\n\n")[0])
    common_arguments(parser, "/tmp/hardware_drivers/create", 57600)
    parser.add_argument("--model", choices=("create1", "create2"), default="create1")
    parser.add_argument("--start-pose", type=_pose, default=(0.0, 0.0, 0.0), metavar="X,Y,YAW",
                        help="true pose at power-up (m, m, rad)")
    parser.add_argument("--pose-file", default=None,
                        help="write the true pose 'x y yaw t' to this file 20 times a second")
    args = parser.parse_args(argv)
    return run_emulator(
        lambda a: CreateEmulator(a.port, a.baud, a.model, a.start_pose, a.pose_file, a.seed), args
    )


if __name__ == "__main__":
    sys.exit(main())
