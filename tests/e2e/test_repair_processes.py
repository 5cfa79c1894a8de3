"""Repairing a wrong tile with a tile already on it, over real processes: the simulated world, one
robot's body, the planner, the auction node and the robot's assembly node, each an OS process on a
ROS domain of its own. The test stands in for the VI robot only: once the triangle is on the wrong
tile, it reports the wrong tile misplaced from two camera positions, so the tile on top is there
for certain (the full team with its inspection is `test_experiment`'s). With nothing left to place,
the robot drives home, before the repair (which it then starts from there) and after it."""

from __future__ import annotations

import json
import math
import subprocess
from collections.abc import Callable, Iterator
from typing import Any

import pytest
from conftest import REPO, STRUCTURES, ros2_command, stop_node_processes
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from ros_helpers.isolated_domains import IsolatedDomain, fresh_domain
from ros_helpers.spinning import spin_until
from rosgraph_msgs.msg import Clock as ClockMsg
from std_msgs.msg import String

from tiling_assembly.structure_file import load_structure
from tiling_assembly_msgs.msg import SimMotion, TileState, TileStateArray
from tiling_ros import team_topics as topics
from tiling_ros.qos import CLOCK, SIM_EVENTS, SIM_MOTION
from tiling_sim import sim_interface as sim
from tiling_sim.robot_motion import start_positions

pytestmark = [pytest.mark.ros, pytest.mark.slow]

PAPER_FILE = STRUCTURES / "paper_14.yaml"
WRONG_TILE_SEED = 1  # sim_world's seed 1 with wrong_tiles 1: an octagon goes where long rectangle 11 should
WRONG, ON_TOP = 11, 13  # triangle 13 rests on 11
OVERHEAD_ERROR = 0.05  # m, config/tiling_sim.yaml's overhead_position_error (the paper's 5 cm)


def _command(package: str, executable: str, namespace: str | None, params: str, *extra: str) -> list[str]:
    return [ros2_command(), "run", package, executable, "--ros-args",
            *(["-r", f"__ns:={namespace}"] if namespace else []),
            "--params-file", str(REPO / "config" / params), "-p", f"structure_file:={PAPER_FILE}",
            "-p", "use_sim_time:=true", *extra]


class Team:
    """The processes, and a node of the test that hears the world's events and the decisions."""

    def __init__(self, domain: IsolatedDomain) -> None:
        robots = "robot_names:=[robot1]"
        commands = {
            "sim_world": _command("tiling_sim", "sim_world", None, "tiling_sim.yaml", "-p", robots,
                                  "-p", f"seed:={WRONG_TILE_SEED}", "-p", "wrong_tiles:=1",
                                  "-p", "real_time_factor:=40.0", "-p", "robot_start_xy:=[0.0]"),
            "sim_robot": _command("tiling_sim", "sim_robot", "/robot1", "tiling_sim.yaml", "-p", robots,
                                  "-p", "robot_start_xy:=[0.0]"),
            "planner_node": _command("planner_node", "planner_node", None, "planner_node.yaml", "-p", robots),
            "auction_node": _command("auction_node", "auction_node", None, "auction_node.yaml"),
            "assembly_node": _command("assembly_node", "assembly_node", "/robot1", "assembly_node.yaml"),
        }
        self.processes = {name: subprocess.Popen(command, cwd=REPO, env=domain.environ(), stdout=subprocess.PIPE,
                                                 stderr=subprocess.STDOUT, text=True)
                          for name, command in commands.items()}
        self.node = Node("repair_processes_test", context=domain.context)
        self.executor = SingleThreadedExecutor(context=domain.context)
        self.executor.add_node(self.node)
        self.events: list[dict[str, Any]] = []
        self.decisions: list[str] = []
        self.now = 0.0
        self.node.create_subscription(String, "/sim/events", lambda m: self.events.append(json.loads(m.data)),
                                      SIM_EVENTS)
        topics.DECISIONS_LOG.subscribe(self.node, lambda m: self.decisions.append(m.data))
        self.node.create_subscription(ClockMsg, "/clock", self.on_clock, CLOCK)
        self.robot_bound_for: list[tuple[float, float]] = []  # where robot1's body says its base goes
        self.node.create_subscription(SimMotion, sim.MOTION,
                                      lambda m: self.robot_bound_for.append((m.x, m.y)), SIM_MOTION)
        self.states_pub = topics.TILE_STATES.publisher(self.node)

    def on_clock(self, msg: ClockMsg) -> None:
        self.now = msg.clock.sec + msg.clock.nanosec * 1e-9

    def spin_until(self, predicate: Callable[[], bool], timeout: float) -> bool:
        return spin_until(self.executor, predicate, timeout)

    def happened(self, kind: str, tile: int) -> bool:
        return any(e["event"] == kind and e.get("tile") == tile for e in self.events)

    def report_misplaced(self, tile: int, camera: tuple[float, float], scans: int) -> None:
        """A scan from `camera` (x, y) that calls `tile` misplaced, as vi_node publishes it."""
        msg = TileStateArray()
        msg.header.frame_id = "map"
        msg.header.stamp.sec = int(self.now)
        msg.header.stamp.nanosec = int((self.now % 1.0) * 1e9)
        msg.camera_pose.position.x, msg.camera_pose.position.y = camera
        msg.camera_pose.orientation.w = 1.0
        msg.states = [TileState(tile_id=tile, state=TileState.MISPLACED, scan_count=scans, physical_support=100 + scans,
                                see_through_support=60, offset_x=0.0, offset_y=0.0, offset_yaw=0.0)]
        self.states_pub.publish(msg)

    def close(self) -> dict[str, str]:
        self.executor.shutdown()
        self.node.destroy_node()
        return stop_node_processes(self.processes)


@pytest.fixture
def team() -> Iterator[Team]:
    bed = Team(fresh_domain())
    try:
        yield bed
    finally:
        outputs = bed.close()  # every process stops cleanly at Ctrl-C
        assert not any("Traceback" in output for output in outputs.values()), outputs


def test_a_wrong_tile_with_a_tile_on_it_comes_off_under_it_and_both_end_right(team: Team) -> None:
    assert team.spin_until(lambda: team.happened("placed", ON_TOP), 240.0), team.events[-5:]
    landed = [e for e in team.events if e["event"] == "misplaced"]
    assert [(e["tile"], e["misplacement"]) for e in landed] == [(WRONG, "wrong_type")]
    # the VI robot's word, from two camera positions 1.4 m apart
    team.report_misplaced(WRONG, (0.9, 0.0), scans=1)
    team.spin_until(lambda: False, 0.5)
    team.report_misplaced(WRONG, (0.0, 0.9), scans=2)
    assert team.spin_until(lambda: any(e["event"] == "complete" for e in team.events), 240.0), team.decisions
    repair = [d for d in team.decisions if f"opened for tile {WRONG} " in d]
    assert len(repair) == 1 and f"{ON_TOP} rests on it and comes off first" in repair[0], team.decisions
    after = [(e["event"], e["tile"]) for e in team.events
             if e["event"] in ("taken_off", "placed") and e["t"] > landed[0]["t"] and e["tile"] in (WRONG, ON_TOP)]
    # 13 placed on the wrong tile; off top down; the right tile in; 13 back on it
    assert after == [("placed", ON_TOP), ("taken_off", ON_TOP), ("taken_off", WRONG), ("placed", WRONG),
                     ("placed", ON_TOP)]
    taken = [e for e in team.events if e["event"] == "taken_off"]
    assert [e["lay_wrong"] for e in taken] == [None, "wrong_type"]  # 13 lay right: it only had to make way
    assert not [d for d in team.decisions if "opened for tile" in d and f" {WRONG} " not in d]  # nothing else
    # with nothing left to place, the robot drives home, out of the cameras' view: where it was first
    # seen, its start as the overhead cameras saw it (the world shows every robot when its clock
    # starts) or as its body reported it, so within the overhead cameras' error of its start
    tiles = load_structure(PAPER_FILE).tiles.values()
    start = start_positions([(float(t.position[0]), float(t.position[1])) for t in tiles], 1)[0]
    assert team.spin_until(lambda: math.dist(team.robot_bound_for[-1], start) <= OVERHEAD_ERROR, 60.0), \
        (start, team.robot_bound_for[-3:])
