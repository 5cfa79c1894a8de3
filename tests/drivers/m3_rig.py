"""One M3 robot as real processes for a test: the Create, Dynamixel and URG emulators on
pseudo-terminals, the three drivers and `m3_robot`, and the test's stand-in for the overhead cameras
(the Create emulator writes its true pose to a file; the URG emulator renders one long rectangle,
lying at `tile_pose`, from that pose; the gripper servo stops on the tile when it closes)."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from processes import Emulator, NodeProcess
from ros_probe import OverheadCamera

from hardware_drivers import dynamixel_protocol as dx

LASER_MOUNT = "0.16,0.0,0.0"
# quicker than the real robot's defaults, to keep the tests short
FAST_SERVOS = ("-p", "joint_max_velocities:=[3.0,3.0,3.0,3.0,3.0,3.0]")
FAST = (*FAST_SERVOS, "-p", "arm_speed:=2.5", "-p", "max_linear:=0.3", "-p", "max_angular:=1.5")
GRIPPER_ON_TILE = dx.radians_to_position(-0.2)  # servo position where the fingers meet a 4 cm tile
ARM_PARAMS = ("config/hardware_drivers.yaml", "config/crustcrawler_arm.yaml")


@contextmanager
def m3_rig(
    directory: Path, start: tuple[float, float, float], tile_pose: tuple[float, float, float]
) -> Iterator[dict[str, Any]]:
    """The rig, up and connected: {"create", "arm", "urg": the emulators, "nodes": name -> process}.
    Everything is stopped at the end, also when the set-up failed half way; no node may have
    printed a traceback."""
    pose_file = directory / "true_pose"
    emulators: list[Emulator] = []
    nodes: list[NodeProcess] = []
    camera = None
    try:
        emulators.append(Emulator("create", directory / "create", "--pose-file", str(pose_file),
                                  "--start-pose", ",".join(str(v) for v in start)))
        emulators.append(Emulator("dynamixel", directory / "arm", "--stall", f"6:{GRIPPER_ON_TILE}"))
        emulators.append(Emulator("urg", directory / "urg", "--robot-pose-file", str(pose_file),
                                  "--laser-mount", LASER_MOUNT, "--tile-pose", ",".join(str(v) for v in tile_pose),
                                  "--noise", "0.003"))
        nodes += [
            NodeProcess("create_base", directory, "-p", f"port:={directory / 'create'}"),
            NodeProcess("crustcrawler_arm", directory, "-p", f"port:={directory / 'arm'}", *FAST_SERVOS,
                        params_files=ARM_PARAMS),
            NodeProcess("hokuyo_urg", directory, "-p", f"port:={directory / 'urg'}"),
            NodeProcess("m3_robot", directory, "-p", "structure_file:=config/structures/paper_14.yaml",
                        "-p", f"laser_mount:=[{LASER_MOUNT}]", *FAST, params_files=ARM_PARAMS),
        ]
        camera = OverheadCamera(pose_file, "/robot1/overhead_pose")
        for node in nodes[:3]:
            node.wait_for_log("connected to the", timeout=20.0)
        create, arm, urg = emulators
        yield {"create": create, "arm": arm, "urg": urg, "nodes": {n.name: n for n in nodes}, "pose_file": pose_file}
    finally:
        if camera is not None:
            camera.close()
        for node in nodes:
            node.stop()
        for emulator in emulators:
            emulator.close()
            # the emulators' event lines beside the nodes' logs, for a failure's post-mortem
            (directory / f"{emulator.kind}_emulator.log").write_text(
                "".join(f"{stamp:.6f} {text}\n" for stamp, text in emulator.lines))
    for node in nodes:
        assert "Traceback" not in node.log(), f"{node.name} printed a traceback:\n{node.log()}"
