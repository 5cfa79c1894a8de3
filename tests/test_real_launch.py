"""The five launch files under the real ROS 2 Jazzy `ros2 launch`: each starts every node it
describes, with the arguments its docstring shows, and at Ctrl-C (SIGINT to `ros2 launch`) every
process finishes cleanly and launch exits 0.

The real launch is not on PyPI: tools/install-real-launch installs it outside the repository, in
$TILING_REAL_LAUNCH (default /opt/ros2-real-launch), and these tests are skipped where it is not.
The hardware launch files drive the device emulators on pseudo-terminals, so the drivers really
connect; the Kinect driver, a third-party package, is stood in for by tests/stand_in_kinect_node.py.
"""

from __future__ import annotations

import contextlib
import os
import re
import signal
import subprocess
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, replace
from pathlib import Path

import pytest
import rclpy
from drivers.processes import Emulator
from rclpy.node import Node
from ros_helpers.isolated_domains import IsolatedDomain, fresh_domain

REPO = Path(__file__).resolve().parent.parent
REAL_LAUNCH = Path(os.environ.get("TILING_REAL_LAUNCH", "/opt/ros2-real-launch"))
STAND_IN_KINECT = "stand_in_kinect"

STARTUP_TIMEOUT = 40.0  # s until every node is in the graph (Open3D's import is slow on a busy machine)
SHUTDOWN_TIMEOUT = 20.0  # s; launch's own SIGTERM and SIGKILL timeouts are 5 s each


def real_launch_installed() -> bool:
    return (REAL_LAUNCH / "python" / "bin" / "ros2").exists() and \
        (REAL_LAUNCH / "interfaces" / "local_setup.sh").exists()


pytestmark = [
    pytest.mark.ros,
    pytest.mark.skipif(
        not real_launch_installed(),
        reason=f"the real ROS 2 launch is not installed in {REAL_LAUNCH} (set TILING_REAL_LAUNCH); "
               "install it with tools/install-real-launch (README: 'Checking the launch files')",
    ),
]


@dataclass(frozen=True)
class LaunchCase:
    package: str
    file: str
    variant: str
    arguments: tuple[str, ...]  # with {create}, {arm}, {urg} (emulator ports), {absent}, {structure}
    nodes: tuple[str, ...]  # fully qualified node names that must all be in the graph
    emulators: tuple[str, ...] = ()  # device emulators to start: create, arm, urg
    log_lines: tuple[str, ...] = ()  # what must be logged before the Ctrl-C (drivers connected...)
    published_topics: tuple[str, ...] = ()  # topics that must have a publisher (remappings)


CONNECTED = {
    "create": "connected to the iRobot Create",
    "arm": "connected to the CrustCrawler arm",
    "urg": "connected to the Hokuyo URG",
}
M3_DRIVERS = ("create_base", "crustcrawler_arm", "hokuyo_urg", "m3_robot")
KINECT = (f"start_kinect:=true kinect_package:={STAND_IN_KINECT} kinect_executable:={STAND_IN_KINECT} "
          "kinect_points_topic:=points").split()

# The ports of devices that are not there: not the defaults (/dev/ttyUSB0...), which on a robot's
# computer are real devices a test must not drive.
ABSENT_DEVICES = ("base_port:={absent}/create", "arm_port:={absent}/arm", "laser_port:={absent}/urg")

CASES = [
    LaunchCase(
        "assembly_node", "assembly_robot.launch.py", "docstring",
        ("namespace:=robot2", "base_port:={create}", "arm_port:={arm}", "laser_port:={urg}"),
        tuple(f"/robot2/{name}" for name in (*M3_DRIVERS, "assembly_node")),
        emulators=("create", "arm", "urg"), log_lines=tuple(CONNECTED.values()),
    ),
    LaunchCase(  # the drivers wait for their devices (retrying) when the Ctrl-C comes
        "assembly_node", "assembly_robot.launch.py", "devices-absent", ABSENT_DEVICES,
        tuple(f"/robot1/{name}" for name in (*M3_DRIVERS, "assembly_node")),
        log_lines=("port {absent}/create does not exist", "port {absent}/arm does not exist",
                   "port {absent}/urg does not exist"),
    ),
    LaunchCase(
        "auction_node", "team.launch.py", "docstring",
        ("structure_file:={structure}", "robot_names:=[robot1, robot2, robot3]"),
        ("/planner_node", "/auction_node"),
        log_lines=("14 tiles for 3 robots",),  # robot_names reached the planner as a list
    ),
    LaunchCase(
        "auction_node", "team.launch.py", "default-robots", ("structure_file:={structure}",),
        ("/planner_node", "/auction_node"), log_lines=("14 tiles for 2 robots",),
    ),
    LaunchCase(
        "hardware_drivers", "m3_robot.launch.py", "docstring",
        ("namespace:=robot1", "base_port:={create}", "arm_port:={arm}", "laser_port:={urg}"),
        tuple(f"/robot1/{name}" for name in M3_DRIVERS),
        emulators=("create", "arm", "urg"), log_lines=tuple(CONNECTED.values()),
    ),
    LaunchCase(
        "hardware_drivers", "vi_robot.launch.py", "docstring",
        ("base_port:={create}", *KINECT),
        ("/vi/create_base", "/vi/base_navigator", "/vi/kinect"),
        emulators=("create",), log_lines=(CONNECTED["create"],),
        published_topics=("/vi/camera/depth/points",),
    ),
    LaunchCase(
        "vi_node", "inspection.launch.py", "docstring",
        ("base_port:={create}", "structure_file:={structure}", *KINECT),
        ("/vi/create_base", "/vi/base_navigator", "/vi/kinect", "/vi/vi_node", "/vi/vi_explorer"),
        emulators=("create",), log_lines=(CONNECTED["create"],),
        published_topics=("/vi/camera/depth/points",),
    ),
    LaunchCase(  # no Kinect, no structure file (waits for /structure), no base
        "vi_node", "inspection.launch.py", "devices-absent", ("base_port:={absent}/create",),
        ("/vi/create_base", "/vi/base_navigator", "/vi/vi_node", "/vi/vi_explorer"),
        log_lines=("port {absent}/create does not exist",),
    ),
]


@pytest.fixture(scope="module")
def stand_in_kinect_prefix(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """An install prefix holding the stand-in Kinect driver as an ament package, as a user's
    Kinect driver would be installed (ros2 launch finds PREFIX/lib/PACKAGE/EXECUTABLE)."""
    prefix = tmp_path_factory.mktemp("stand_in_kinect")
    index = prefix / "share" / "ament_index" / "resource_index" / "packages"
    index.mkdir(parents=True)
    (index / STAND_IN_KINECT).touch()
    (prefix / "lib" / STAND_IN_KINECT).mkdir(parents=True)
    (prefix / "lib" / STAND_IN_KINECT / STAND_IN_KINECT).symlink_to(REPO / "tests" / "stand_in_kinect_node.py")
    return prefix


@contextlib.contextmanager
def graph_observer(domain: IsolatedDomain) -> Iterator[Node]:
    """A node of the test's own in `domain`, to look at the graph (no spinning needed for that)."""
    node = rclpy.create_node("real_launch_test_observer", context=domain.context)
    try:
        yield node
    finally:
        node.destroy_node()


@contextlib.contextmanager
def emulators(kinds: tuple[str, ...], directory: Path) -> Iterator[dict[str, str]]:
    """The device emulators `kinds` on pseudo-terminals; their ports by kind."""
    program = {"create": "create", "arm": "dynamixel", "urg": "urg"}
    with contextlib.ExitStack() as stack:
        ports = {}
        for kind in kinds:
            emulator = Emulator(program[kind], directory / kind)
            stack.callback(emulator.close)
            ports[kind] = str(emulator.port)
        yield ports


class LaunchProcess:
    """`ros2 launch` (the real one) as a process of its own session; its output collected line by line."""

    def __init__(self, command: list[str], environment: dict[str, str]) -> None:
        self.lines: list[str] = []
        self.process = subprocess.Popen(
            command, cwd=REPO, env=environment, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
            text=True, bufsize=1, start_new_session=True,  # the terminal's Ctrl-C is not ours to pass
        )
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.process.stdout is not None
        for line in self.process.stdout:
            self.lines.append(line.rstrip("\n"))

    @property
    def output(self) -> str:
        return "\n".join(self.lines)

    def running(self) -> bool:
        return self.process.poll() is None

    def interrupt(self, timeout: float) -> int | None:
        """SIGINT to `ros2 launch` alone, as Ctrl-C does; its exit code, None if it outlived `timeout`."""
        self.process.send_signal(signal.SIGINT)
        try:
            code = self.process.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            return None
        self._reader.join(timeout=5.0)
        return code

    def leftovers(self) -> bool:
        """Whether a process launch started is still alive (launch and its nodes share one group)."""
        try:
            os.killpg(self.process.pid, 0)
        except ProcessLookupError:
            return False
        return True

    def kill_everything(self) -> None:
        """Whatever is left of launch and its nodes, after a failed test."""
        with contextlib.suppress(ProcessLookupError):
            os.killpg(self.process.pid, signal.SIGKILL)
        self.process.wait()


def launch_environment(domain: int, kinect_prefix: Path) -> dict[str, str]:
    environment = {**os.environ, "ROS_DOMAIN_ID": str(domain), "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
                   "TILING_REAL_LAUNCH": str(REAL_LAUNCH), "RCUTILS_COLORIZED_OUTPUT": "0",
                   "PYTHONUNBUFFERED": "1"}
    environment["AMENT_PREFIX_PATH"] = os.pathsep.join(
        p for p in (str(kinect_prefix), environment.get("AMENT_PREFIX_PATH", "")) if p)
    return environment


def wait_until_up(launch: LaunchProcess, observer: Node, case: LaunchCase) -> None:
    """Until every node is in the graph, every expected line logged and every topic published."""
    deadline = time.monotonic() + STARTUP_TIMEOUT
    while True:
        missing = missing_parts(launch, observer, case)
        if not missing:
            return
        if not launch.running() or "process has died" in launch.output or time.monotonic() > deadline:
            pytest.fail(f"{case.file}: not up within {STARTUP_TIMEOUT} s or a process died "
                        f"(launch running: {launch.running()}); "
                        f"missing {missing}; launch output:\n{launch.output[-6000:]}")
        time.sleep(0.2)


def missing_parts(launch: LaunchProcess, observer: Node, case: LaunchCase) -> list[str]:
    in_graph = {f"{ns.rstrip('/')}/{name}" for name, ns in observer.get_node_names_and_namespaces()}
    output = launch.output
    missing = [f"node {n}" for n in case.nodes if n not in in_graph]
    missing += [f"log line '{line}'" for line in case.log_lines if line not in output]
    missing += [f"publisher on {t}" for t in case.published_topics if not observer.get_publishers_info_by_topic(t)]
    return missing


def processes_in(output: str, event: str) -> set[str]:
    """The processes launch reported `event` for ('process started with pid', ...)."""
    return set(re.findall(rf"^\[INFO\] \[([\w.-]+)\]: {re.escape(event)}", output, flags=re.MULTILINE))


def assert_stopped_cleanly(case: LaunchCase, code: int | None, output: str) -> None:
    assert code is not None, f"{case.file}: launch still running {SHUTDOWN_TIMEOUT} s after Ctrl-C:\n{output[-6000:]}"
    started = processes_in(output, "process started with pid")
    finished = processes_in(output, "process has finished cleanly")
    assert len(started) == len(case.nodes), f"{case.file}: started {sorted(started)}"
    assert finished == started, (f"{case.file}: not finished cleanly at Ctrl-C: {sorted(started - finished)}\n"
                                 f"{output[-6000:]}")
    for trouble in ("Traceback", "terminate called", "process has died", "exit code -6", "exit code -15",
                    "sending signal 'SIGTERM'", "sending signal 'SIGKILL'"):
        assert trouble not in output, f"{case.file}: '{trouble}' at Ctrl-C:\n{output[-6000:]}"
    assert code == 0, f"{case.file}: ros2 launch exited with {code}:\n{output[-6000:]}"


@pytest.mark.parametrize("case", CASES, ids=lambda c: f"{c.file}-{c.variant}")
def test_launch_file_starts_every_node_and_stops_cleanly_at_ctrl_c(
    case: LaunchCase, stand_in_kinect_prefix: Path, tmp_path: Path,
) -> None:
    domain = fresh_domain()  # of this launch alone: nodes of an earlier case still fading from the graph
    with emulators(case.emulators, tmp_path) as ports, graph_observer(domain) as observer:
        values = {**ports, "absent": str(tmp_path / "absent"),
                  "structure": str(REPO / "config" / "structures" / "paper_14.yaml")}
        case = replace(case, arguments=tuple(a.format(**values) for a in case.arguments),
                       log_lines=tuple(line.format(**values) for line in case.log_lines))
        command = [str(REPO / "tools" / "real-launch-env"), "ros2", "launch", case.package, case.file, *case.arguments]
        launch = LaunchProcess(command, launch_environment(domain.domain_id, stand_in_kinect_prefix))
        try:
            wait_until_up(launch, observer, case)
            code = launch.interrupt(SHUTDOWN_TIMEOUT)
            assert_stopped_cleanly(case, code, launch.output)
            assert not launch.leftovers(), f"{case.file}: a process outlived ros2 launch"
        finally:
            launch.kill_everything()
