"""Hokuyo URG-04LX emulator on a pseudo-terminal (SCIP 1.1 at power-up, SCIP 2.0 after the
switch), scanning a simple scene: a tile in front of the laser, optional walls.

    ros2 run hardware_drivers urg_emulator --port /tmp/m3/urg --tile-pose 0.25,0.0,0.3
        [--tile-polygon "-0.085,-0.02;0.085,-0.02;0.085,0.02;-0.085,0.02"]
        [--segments "1.0,-1.0,1.0,1.0"] [--noise 0.003]
        [--robot-pose-file /tmp/m3/pose --laser-mount 0.12,0,0]

The scene is given in the laser frame, or, with ``--robot-pose-file`` (written by the Create
emulator), in the world frame: the laser then sees the scene from wherever the robot has driven.
Ranges are ray-cast against the tile's outline and the segments, with Gaussian noise and 1 mm
quantisation; no echo within DMAX gives the error code 0.

Commands: QT, BM, RS, PP, VV, II, GD/GS, MD/MS (continuous scans at 600 rpm, 3- or 2-character
encoding), SCIP2.0; SCIP 1.1 answers every SCIP 2.0 command with an ``E`` status until switched.
Control lines on stdin: ``tile X,Y,YAW|none``, ``corrupt N`` (next N scans with a damaged data
line), ``partial`` (next scan cut short), ``fault NN`` (scans report hardware status NN; 0 clears),
``garbage N``, ``silence S``, ``unplug S``, ``plug``, ``quit``.
"""

from __future__ import annotations

import argparse
import math
import sys
import time

import numpy as np

from hardware_drivers import scip
from hardware_drivers.emulators.pty_device import EmulatorApp, common_arguments, run_emulator
from hardware_drivers.planar_pose import Pose2D

MAX_STEP = 768  # the URG-04LX's last step number (its 270 degree window is AMIN..AMAX inside it)
LONG_RECTANGLE = "-0.085,-0.02;0.085,-0.02;0.085,0.02;-0.085,0.02"


def parse_polygon(text: str) -> np.ndarray:
    points = np.array([[float(v) for v in p.split(",")] for p in text.split(";") if p.strip()])
    if points.ndim != 2 or points.shape[1] != 2 or len(points) < 3:
        raise ValueError("a polygon is 'x,y;x,y;x,y...' with at least 3 corners")
    return points


def parse_pose(text: str) -> Pose2D:
    values = [float(v) for v in text.split(",")]
    if len(values) != 3:
        raise ValueError("a pose is X,Y,YAW")
    return Pose2D(*values)


def ray_cast(origin: Pose2D, angles: np.ndarray, segments: np.ndarray) -> np.ndarray:
    """Distance along each ray (angles in the origin's frame) to the nearest segment; inf if none.

    segments: (M, 4) x1, y1, x2, y2 in the scene frame.
    """
    if len(segments) == 0:
        return np.full(len(angles), np.inf)
    world = origin.yaw + angles
    d = np.column_stack([np.cos(world), np.sin(world)])  # (N, 2)
    p, e = segments[:, :2], segments[:, 2:] - segments[:, :2]  # (M, 2)
    w = p - np.array([origin.x, origin.y])  # (M, 2)
    denominator = d[:, None, 0] * e[None, :, 1] - d[:, None, 1] * e[None, :, 0]  # (N, M)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (w[None, :, 0] * e[None, :, 1] - w[None, :, 1] * e[None, :, 0]) / denominator
        u = (w[None, :, 0] * d[:, None, 1] - w[None, :, 1] * d[:, None, 0]) / denominator
    hit = (np.abs(denominator) > 1e-12) & (t > 1e-9) & (u >= 0.0) & (u <= 1.0)
    return np.where(hit, t, np.inf).min(axis=1)


class UrgEmulator(EmulatorApp):
    tick_period = 0.005
    supports_partial = True

    def __init__(self, link: str, baud: int, scip_version: str, tile_polygon: np.ndarray,
                 tile_pose: Pose2D | None, segments: np.ndarray, noise: float,
                 robot_pose_file: str | None, laser_mount: Pose2D, seed: int) -> None:
        super().__init__(link, baud, seed)
        self.parameters = scip.URG_04LX
        self.boot_version = scip_version
        self.tile_polygon = tile_polygon
        self.tile_pose = tile_pose
        self.segments = segments
        self.noise = noise
        self.robot_pose_file = robot_pose_file
        self.laser_mount = laser_mount
        self.np_rng = np.random.default_rng(seed)
        self.start_time = time.monotonic()
        self.fault_status = 0
        self._input = b""
        self._power_up()

    def _power_up(self) -> None:
        self.version = self.boot_version
        self.laser_on = False
        self.streaming: dict | None = None  # the active MD/MS request
        self._input = b""

    def on_plugged(self) -> None:
        self._power_up()

    # ------------------------------------------------------------------ the scene
    def laser_pose(self) -> Pose2D:
        if not self.robot_pose_file:
            return Pose2D()
        try:
            with open(self.robot_pose_file) as handle:
                x, y, yaw = (float(v) for v in handle.read().split()[:3])
        except (OSError, ValueError):
            return Pose2D()
        return Pose2D(x, y, yaw).compose(self.laser_mount)

    def scene_segments(self) -> np.ndarray:
        parts = [self.segments.reshape(-1, 4)]
        if self.tile_pose is not None:
            corners = self.tile_pose.transform_points(self.tile_polygon)
            parts.append(np.hstack([corners, np.roll(corners, -1, axis=0)]))
        return np.vstack(parts)

    def measure(self, start: int, end: int, cluster: int) -> list[int]:
        steps = np.arange(start, end + 1)
        angles = (steps - self.parameters.afrt) * 2.0 * math.pi / self.parameters.ares
        distances = ray_cast(self.laser_pose(), angles, self.scene_segments())
        noisy = distances + self.np_rng.normal(0.0, self.noise, len(distances)) if self.noise > 0 \
            else distances
        mm = np.where(np.isfinite(noisy), np.round(noisy * 1000.0), 0.0)
        valid = (mm >= self.parameters.dmin) & (mm <= self.parameters.dmax)
        raw = np.where(valid, mm, 0).astype(int)
        if cluster > 1:  # the sensor reports the minimum valid value of each cluster
            groups = [raw[i : i + cluster] for i in range(0, len(raw), cluster)]
            raw = np.array([min((v for v in g if v), default=0) for g in groups])
        return [int(v) for v in raw]

    def timestamp(self) -> int:
        return int((time.monotonic() - self.start_time) * 1000.0) % (1 << 24)

    # ------------------------------------------------------------------ commands
    def on_bytes(self, data: bytes, now: float) -> None:
        self._input += data.replace(b"\r", b"\n")
        while b"\n" in self._input:
            line, self._input = self._input.split(b"\n", 1)
            if line:
                self.execute(line, now)

    def execute(self, line: bytes, now: float) -> None:
        if self.version == "1.1":
            if line.startswith(b"SCIP2.0"):
                self.version = "2.0"
                self.send(line + b"\n0\n\n")
                self.emit("scip 2.0")
            else:
                self.send(line + b"\nE\n\n")  # SCIP 1.1 does not know SCIP 2.0 commands
            return
        name = line[:2]
        if line.startswith(b"SCIP2.0"):
            self.send(scip.status_reply(line, b"0E"))
        elif name == b"QT":
            self.streaming = None
            self.laser_on = False
            self.send(scip.status_reply(line, b"00"))
        elif name == b"RS":
            self.streaming = None
            self.laser_on = False
            self.send(scip.status_reply(line, b"00"))
        elif name == b"BM":
            self.send(scip.status_reply(line, b"02" if self.laser_on else b"00"))
            self.laser_on = True
        elif name == b"PP":
            self.send(scip.status_reply(line, b"00", scip.parameter_lines(self.parameters.to_pp())))
        elif name == b"VV":
            self.send(scip.status_reply(line, b"00", scip.parameter_lines({
                "VEND": "Hokuyo Automatic Co.,Ltd.", "PROD": "SOKUIKI Sensor URG-04LX (emulated)",
                "FIRM": "3.4.03", "PROT": "SCIP 2.0", "SERI": "H0000001"})))
        elif name == b"II":
            self.send(scip.status_reply(line, b"00", scip.parameter_lines({
                "MODL": self.parameters.model, "LASR": "ON" if self.laser_on else "OFF",
                "SCSP": f"Initial({self.parameters.scan_rpm}[rpm])", "MESM": "Measuring by Sensitive Mode",
                "SBPS": "USB only", "TIME": scip.encode(self.timestamp(), 4).decode(),
                "STAT": "Sensor works well."})))
        elif name in (b"GD", b"GS", b"MD", b"MS"):
            self._measurement_command(line, now)
        else:
            self.send(scip.status_reply(line, b"0E"))

    def _measurement_command(self, line: bytes, now: float) -> None:
        name = line[:2]
        continuous = name in (b"MD", b"MS")
        body = line[2:].split(b";")[0]
        expected = 13 if continuous else 10
        if len(body) != expected or not body.isdigit():
            self.send(scip.status_reply(line, b"0C"))
            return
        start, end, cluster = int(body[0:4]), int(body[4:8]), int(body[8:10])
        if end > MAX_STEP or start > end:
            self.send(scip.status_reply(line, b"04" if end > MAX_STEP else b"05"))
            return
        chars = 3 if name in (b"MD", b"GD") else 2
        cluster = max(1, cluster)
        if not continuous:
            if not self.laser_on:
                self.send(scip.status_reply(line, b"10"))
                return
            ranges = self.measure(start, end, cluster)
            self.send(scip.scan_reply(line, b"00", self.timestamp(), ranges, chars))
            return
        interval, scans = int(body[10:11]), int(body[11:13])
        self.laser_on = True
        self.streaming = {
            "echo": line, "start": start, "end": end, "cluster": cluster, "chars": chars,
            "interval": interval, "remaining": scans, "forever": scans == 0,
            "next": now + self.parameters.scan_time, "tag": line[15:],
        }
        self.send(scip.status_reply(line, b"00"))

    # ------------------------------------------------------------------ periodic scans
    def tick(self, now: float) -> None:
        request = self.streaming
        if request is None or now < request["next"]:
            return
        period = self.parameters.scan_time * (request["interval"] + 1)
        request["next"] = max(request["next"] + period, now)
        if now < self.silent_until:
            return
        if request["forever"]:
            remaining = 0
        else:
            request["remaining"] -= 1
            remaining = request["remaining"]
        echo = request["echo"][:13] + f"{remaining:02d}".encode() + request["echo"][15:]
        if self.fault_status:
            self.send(scip.status_reply(echo, f"{self.fault_status:02d}".encode()))
        else:
            ranges = self.measure(request["start"], request["end"], request["cluster"])
            reply = bytearray(scip.scan_reply(echo, b"99", self.timestamp(), ranges, request["chars"]))
            if self.take_corruption():
                position = len(echo) + 12 + 30  # inside the first data line
                reply[position] = 0x30 + (reply[position] - 0x30 + 1) % 64
            if self.take_partial():
                reply = reply[: len(reply) // 2]
            self.send(bytes(reply))
        if not request["forever"] and request["remaining"] <= 0:
            self.streaming = None
            self.laser_on = False

    def command(self, words: list[str], now: float) -> bool:
        verb = words[0]
        if verb == "tile":
            self.tile_pose = None if words[1] == "none" else parse_pose(words[1])
            self.emit(f"tile {words[1]}")
        elif verb == "fault":
            self.fault_status = int(words[1])
            self.emit(f"fault {self.fault_status}")
        else:
            return False
        return True


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="urg_emulator", description=__doc__.split("\n\n")[0])
    common_arguments(parser, "/tmp/hardware_drivers/urg", 19200)
    parser.add_argument("--scip", choices=("1.1", "2.0"), default="1.1",
                        help="protocol at power-up (the URG-04LX boots in SCIP 1.1)")
    parser.add_argument("--tile-polygon", default=LONG_RECTANGLE,
                        help="the tile's outline in its frame, 'x,y;x,y;...' (m); default: long rectangle")
    parser.add_argument("--tile-pose", default="0.25,0.0,0.0",
                        help="X,Y,YAW of the tile frame in the scene (m, rad), or 'none'")
    parser.add_argument("--segments", default="",
                        help="walls as 'x1,y1,x2,y2;...' in the scene frame (m)")
    parser.add_argument("--noise", type=float, default=0.003, help="range noise sigma (m), default 0.003")
    parser.add_argument("--robot-pose-file", default=None,
                        help="true pose file of the robot (create_emulator --pose-file): "
                        "the scene is then in the world frame")
    parser.add_argument("--laser-mount", default="0,0,0", help="X,Y,YAW of the laser on the robot base")
    args = parser.parse_args(argv)

    def make(a: argparse.Namespace) -> UrgEmulator:
        segments = np.array([[float(v) for v in s.split(",")] for s in a.segments.split(";") if s.strip()])
        if segments.size and (segments.ndim != 2 or segments.shape[1] != 4):
            raise ValueError("segments are 'x1,y1,x2,y2;...'")
        tile_pose = None if a.tile_pose == "none" else parse_pose(a.tile_pose)
        return UrgEmulator(a.port, a.baud, a.scip, parse_polygon(a.tile_polygon), tile_pose,
                           segments.reshape(-1, 4), a.noise, a.robot_pose_file, parse_pose(a.laser_mount),
                           a.seed)

    return run_emulator(make, args)


if __name__ == "__main__":
    sys.exit(main())
