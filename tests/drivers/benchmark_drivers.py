"""Measurements of the hardware drivers (not a test: prints figures; run it on a quiet machine).

    tools/workspace-env python tests/drivers/benchmark_drivers.py [--quick]

1. Tile localization error: every tile type of the paper's structure at random poses 0.18-0.45 m
   in front of a URG-04LX (ray cast, Gaussian range noise 3 mm, 1 mm steps); and through the real
   URG driver reading the URG emulator over a pty.
2. Watchdog stop latency: time from the last velocity command to the wheels' stop as the Create
   emulator sees it (driver in this process; the emulator in its own).
3. Reconnect time: from the emulated device reappearing after an unplug to the driver having
   completed its handshake, for the Create, the Dynamixel bus and the URG.
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from processes import REPO, Emulator
from test_tile_localization import scan_of, symmetric_yaw_error

from hardware_drivers.create_driver import CreateConfig, CreateDriver
from hardware_drivers.dynamixel_driver import ArmConfig, ArmDriver, JointConfig
from hardware_drivers.planar_pose import Pose2D
from hardware_drivers.tile_localization import find_tile, footprint_of, rotational_symmetry
from hardware_drivers.urg_driver import UrgConfig, UrgDriver
from tiling_assembly.structure_file import load_structure


def summary(values: list[float], unit: str, scale: float = 1.0) -> str:
    ordered = sorted(v * scale for v in values)
    p95 = ordered[min(len(ordered) - 1, round(0.95 * (len(ordered) - 1)))]
    return (f"median {statistics.median(ordered):.2f} {unit}, 95th {p95:.2f} {unit}, "
            f"max {ordered[-1]:.2f} {unit} (n={len(ordered)})")


def localization_synthetic(trials: int) -> None:
    types = load_structure(REPO / "config" / "structures" / "paper_14.yaml").tile_types
    rng = np.random.default_rng(2024)
    print("1a. tile localization on synthetic scans (noise sigma 3 mm, 1 mm steps)")
    all_errors: list[float] = []
    misses = 0
    for name in sorted(types):
        polygon = footprint_of(types[name])
        symmetry = rotational_symmetry(polygon)
        errors, yaw_errors, times = [], [], []
        for _ in range(trials):
            truth = Pose2D(rng.uniform(0.18, 0.45), rng.uniform(-0.12, 0.12), rng.uniform(-math.pi, math.pi))
            scan = scan_of([(polygon, truth)], 0.003, rng)
            start = time.perf_counter()
            detection = find_tile(scan, polygon)
            times.append(time.perf_counter() - start)
            if detection is None:
                misses += 1
                continue
            errors.append(math.hypot(detection.pose.x - truth.x, detection.pose.y - truth.y))
            yaw_errors.append(symmetric_yaw_error(detection.pose.yaw, truth.yaw, symmetry))
        all_errors += errors
        print(f"   {name:15s} position {summary(errors, 'mm', 1000)}; yaw median "
              f"{math.degrees(statistics.median(yaw_errors)):.1f} deg, "
              f"max {math.degrees(max(yaw_errors)):.1f} deg; "
              f"{statistics.median(times) * 1000:.0f} ms per scan")
    print(f"   all types: position {summary(all_errors, 'mm', 1000)}; not found: {misses}")


def localization_through_the_driver(directory: Path, poses: int) -> None:
    print("1b. tile localization through the URG driver and the URG emulator (noise sigma 3 mm)")
    rectangle = np.array([[-0.085, -0.02], [0.085, -0.02], [0.085, 0.02], [-0.085, 0.02]])
    emulator = Emulator("urg", directory / "urg_loc", "--baud", "0", "--noise", "0.003",
                        "--tile-pose", "0.3,0,0")
    driver = UrgDriver(UrgConfig(port=str(directory / "urg_loc")))
    driver.start()
    rng = np.random.default_rng(7)
    errors = []
    try:
        assert driver.wait_connected(10.0)
        for _ in range(poses):
            truth = Pose2D(rng.uniform(0.2, 0.4), rng.uniform(-0.1, 0.1), rng.uniform(-math.pi, math.pi))
            emulator.send(f"tile {truth.x},{truth.y},{truth.yaw}")
            emulator.wait_for("tile ")
            sequence = driver.latest_scan()[0]
            while driver.latest_scan()[0] < sequence + 2:  # a scan taken after the move
                time.sleep(0.01)
            detection = find_tile(driver.latest_scan()[1], rectangle)
            errors.append(math.inf if detection is None else detection.pose.distance_to(truth))
    finally:
        driver.stop()
        emulator.close()
    print(f"   long_rectangle position {summary(errors, 'mm', 1000)}")


def watchdog_latency(directory: Path, trials: int) -> None:
    print("2. watchdog stop latency (last Drive command -> the emulator's wheels at 0; set to 0.2 s)")
    emulator = Emulator("create", directory / "create_wd")
    driver = CreateDriver(CreateConfig(port=str(directory / "create_wd")))
    driver.start()
    latencies = []
    try:
        assert driver.wait_connected(5.0)
        for _ in range(trials):
            emulator.drain()
            driver.drive(0.1, 0.0)
            last = time.monotonic()
            emulator.wait_for("drive 100 100", 2.0)
            stop = emulator.wait_for("drive 0 0", 2.0)
            latencies.append(float(stop.split("t=")[1]) - last)
            time.sleep(0.1)
    finally:
        driver.stop()
        emulator.close()
    print(f"   {summary(latencies, 's')}; beyond the 0.2 s timeout: median "
          f"{(statistics.median(latencies) - 0.2) * 1000:.0f} ms")


def reconnect_times(directory: Path, trials: int) -> None:
    print("3. reconnect time (device back after 0.6-1.4 s away -> driver connected; retries every 0.5 s)")
    joints = tuple(JointConfig(f"j{i}", i, lower=-1.0, upper=1.0) for i in range(1, 7))
    rigs = {
        "iRobot Create": ("create", (), lambda p: CreateDriver(CreateConfig(port=p))),
        "Dynamixel arm": ("dynamixel", (), lambda p: ArmDriver(ArmConfig(port=p, joints=joints))),
        "Hokuyo URG": ("urg", ("--baud", "0"), lambda p: UrgDriver(UrgConfig(port=p))),
    }
    for label, (kind, extra, make) in rigs.items():
        port = directory / f"{kind}_rc"
        emulator = Emulator(kind, port, *extra)
        driver = make(str(port))
        driver.start()
        times = []
        rng = np.random.default_rng(3)
        try:
            assert driver.wait_connected(10.0)
            for _ in range(trials):
                before = driver.health.counter("connects")
                emulator.send(f"unplug {rng.uniform(0.6, 1.4):.3f}")  # back at any phase of the retries
                back = emulator.wait_for("ready", 5.0)
                while driver.health.counter("connects") == before:
                    time.sleep(0.005)
                times.append(driver.last_connect_time - float(back.split("t=")[1]))
        finally:
            driver.stop()
            emulator.close()
        print(f"   {label:14s} {summary(times, 's')}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="fewer trials")
    args = parser.parse_args()
    trials = 10 if args.quick else 50
    with tempfile.TemporaryDirectory() as directory:
        localization_synthetic(trials)
        localization_through_the_driver(Path(directory), 5 if args.quick else 20)
        watchdog_latency(Path(directory), 5 if args.quick else 20)
        reconnect_times(Path(directory), 3 if args.quick else 8)
    return 0


if __name__ == "__main__":
    sys.exit(main())
