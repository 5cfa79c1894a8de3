"""The settings of the simulated testbed's three kinds of process, with defaults and descriptions.

`sim_world` (the clock, the physical structure, faults, overhead localization), `sim_robot` (one
assembly robot's body) and `sim_vi` (the VI robot's body) read the same `config/tiling_sim.yaml`
(`/**: ros__parameters:`, so every node of the file's command line gets every value). Each node
declares only the fields of its own settings class below, as ROS parameters with the same names
and descriptions; rclpy leaves the file's other values alone, so a node ignores what is meant for
the others. What all of them must agree on (the structure, the team, where everybody starts) is
`SimLayout`, the base of every class. Lengths in m, angles in rad, times in s unless named.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace
from typing import Any

from tiling_assembly.structure import Structure
from tiling_ros.parameters import setting
from tiling_sim.robot_motion import MotionModel, Point2, start_positions

Pose2 = tuple[float, float, float]  # x, y, yaw (m, rad) in map

VI_ROBOT = "vi"  # the VI robot's name when there is one: its namespace and the prefix of its topics


@dataclass(frozen=True)
class SimLayout:
    """What every simulated part knows of the testbed: the structure, the team, where it starts."""

    structure_file: str = setting("", "Structure YAML being built (required).")
    robot_names: list[str] = setting(  # noqa: RUF009 - a field() with a default_factory
        ["robot1", "robot2"], "Simulated assembly robots (their namespaces).")
    robot_start_xy: list[float] = setting(  # noqa: RUF009 - a field() with a default_factory
        [0.0], "x1, y1, x2, y2, ... start positions of the robots in map (m); fewer than 2 numbers: "
        "spread on a circle around the structure.")
    vi_robot_names: list[str] = setting(  # noqa: RUF009 - a field() with a default_factory
        [VI_ROBOT], "Simulated VI (scanning) robots (their namespaces).")
    vi_start_pose: list[float] = setting(  # noqa: RUF009 - a field() with a default_factory
        [0.9, 0.0, math.pi], "x, y, yaw of each VI robot's base at the start, 3 numbers per robot; 3 numbers "
        "for several robots: the first stands there, the others as far round the structure's centre.")
    seed: int = setting(1, "Seed of every random choice of the testbed (faults, localization errors, "
                            "Kinect noise).")
    robot_size: list[float] = setting(  # noqa: RUF009 - a field() with a default_factory
        [0.33, 0.33, 0.35], "Box standing for a robot: x, y, z size (m).")
    robot_clearance: float = setting(
        0.05, "m two robots' bases keep apart: a robot waits, or stops elsewhere, while another stands where "
        "it needs to be.")

    @classmethod
    def names(cls) -> list[str]:
        return [f.name for f in fields(cls)]

    @classmethod
    def description(cls, name: str) -> str:
        return next(f.metadata["description"] for f in fields(cls) if f.name == name)

    @classmethod
    def from_values(cls, values: dict[str, Any], source: str = "") -> Any:
        """Settings with `values` (name -> value, as ROS parameters give them) applied and checked;
        a ValueError names the parameter and the problem in one line."""
        defaults = cls()
        known = set(cls.names())
        changes = {}
        for name, value in values.items():
            if name not in known:
                raise _bad(source, f"unknown parameter '{name}'")
            changes[name] = _coerce(name, value, getattr(defaults, name), source)
        settings = replace(defaults, **changes)
        settings.check(source)
        return settings

    def check(self, source: str) -> None:
        if not self.structure_file:
            raise _bad(source, "parameter 'structure_file' is required")
        if not [r for r in self.robot_names if r]:
            raise _bad(source, "parameter 'robot_names' is empty: the testbed needs an assembly robot")
        if not self.vi_team or len(set(self.vi_team)) != len(self.vi_team):
            raise _bad(source, "parameter 'vi_robot_names' needs one or more different names")
        if len(self.vi_start_pose) not in (3, 3 * len(self.vi_team)):
            raise _bad(source, "parameter 'vi_start_pose' needs x, y, yaw (for every VI robot, or for the first)")
        if len(self.robot_size) != 3 or min(self.robot_size) <= 0 or self.robot_clearance < 0:
            raise _bad(source, "parameter 'robot_size' needs 3 positive sizes, 'robot_clearance' must not be negative")
        if len(self.robot_start_xy) >= 2 and len(self.robot_start_xy) != 2 * len(self.team):
            raise _bad(source, f"parameter 'robot_start_xy' needs 2 numbers per robot "
                             f"({len(self.team)}), got {len(self.robot_start_xy)}")

    @property
    def team(self) -> list[str]:
        return [r for r in self.robot_names if r]

    def robot_starts(self, structure: Structure) -> dict[str, Point2]:
        """Where each assembly robot stands at the start."""
        starts = list(self.robot_start_xy)
        if len(starts) < 2:  # automatic
            centres = [(tile.position[0], tile.position[1]) for tile in structure.tiles.values()]
            return dict(zip(self.team, start_positions(centres, len(self.team)), strict=True))
        return {r: (starts[2 * k], starts[2 * k + 1]) for k, r in enumerate(self.team)}

    @property
    def vi_team(self) -> list[str]:
        return [r for r in self.vi_robot_names if r]

    def vi_starts(self, structure: Structure) -> dict[str, Pose2]:
        """Where each VI robot stands at the start: as given, or the first as given and the others
        turned round the structure's centre by equal steps (they face the same way on it)."""
        given = list(self.vi_start_pose)
        if len(given) == 3 * len(self.vi_team):
            return {r: (given[3 * k], given[3 * k + 1], given[3 * k + 2]) for k, r in enumerate(self.vi_team)}
        (low, high), (x, y, yaw) = structure.bounds, given
        cx, cy = (low[0] + high[0]) / 2, (low[1] + high[1]) / 2
        starts = {}
        for k, robot in enumerate(self.vi_team):
            turn = 2 * math.pi * k / len(self.vi_team)
            c, s = math.cos(turn), math.sin(turn)
            starts[robot] = (cx + c * (x - cx) - s * (y - cy), cy + s * (x - cx) + c * (y - cy), yaw + turn)
        return starts


@dataclass(frozen=True)
class WorldSettings(SimLayout):
    """`sim_world`: the clock, the physical structure, faults, overhead localization."""

    real_time_factor: float = setting(
        20.0, "How much faster than the wall clock simulated time runs (at the wall clock's pace while "
        "the scan the VI robot stopped for is judged: the inspection's real cost).")
    clock_step: float = setting(
        0.05, "s of wall-clock time between two /clock messages (every node of the team wakes for each: "
        "at 0.02 s the ticks alone cost each rclpy process about 6% of a core, 10 robots a whole core).")
    clock_report_period: float = setting(
        60.0, "s of wall-clock time between two log lines on how fast simulated time ran and what held it (0: none).")
    wait_for_start: bool = setting(False, "Hold simulated time at 0 until a message on /sim/start.")
    removals: int = setting(0, "Tiles to remove during the build.")
    removal_window_start: float = setting(40.0, "s of simulated time from which removals may happen.")
    removal_window_end: float = setting(200.0, "s of simulated time by which removals happen.")
    drop_probability: float = setting(0.0, "Chance that a tile slips from the gripper during a placement.")
    misplacements: int = setting(0, "Placements of the build that land shifted 2-5 cm or turned 15-45 degrees.")
    wrong_tiles: int = setting(0, "Placements of the build that put down a tile of the wrong type (same height, "
                                  "from the nearest other cache).")
    overhead_position_error: float = setting(0.05, "Largest overhead localization error, m.")
    overhead_yaw_error_deg: float = setting(10.0, "Largest overhead heading error, degrees.")
    scan_hold_limit: float = setting(
        30.0, "Longest the clock waits (s of wall time) for a VI robot's scan it holds for (stopped until "
        "judged, or at a scan's stamp + scan_period until the next) before running on: the VI body died "
        "or its messages were lost.")
    start_window: float = setting(
        1.0, "s of wall time simulated time stays at its start for the assembly robots' first goals (a "
        "robot on a loaded host would otherwise begin seconds late).")
    vi_start_window: float = setting(
        12.0, "s of wall time simulated time stays at its start at most until every VI robot has set off for its "
        "first viewpoint (its explorer waits a few seconds of wall time to find the other VI robots).")
    body_hold_limit: float = setting(
        5.0, "Longest the clock waits (s of wall time) at the end of an assembly robot's phase for its body "
        "to say what it does next before running on without it: the body died or its link is down.")
    reaction_window: float = setting(
        0.5, "s of wall time the clock stays at the moment an assembly robot's goal ended, even once that robot "
        "has gone on: the other robots' reactions to it (a robot waiting for the tile it placed) begin at that "
        "moment, and robots asking for room then are answered in the team's order (see "
        "tiling_sim/standing_room.py).")

    def check(self, source: str) -> None:
        super().check(source)
        if self.real_time_factor <= 0 or self.clock_step <= 0:
            raise _bad(source, "parameters 'real_time_factor' and 'clock_step' must be positive")
        if not 0.0 <= self.drop_probability <= 1.0:
            raise _bad(source, "parameter 'drop_probability' must lie in [0, 1]")
        if self.misplacements < 0 or self.wrong_tiles < 0:
            raise _bad(source, "parameters 'misplacements' and 'wrong_tiles' must not be negative")
        if self.removals < 0 or self.removal_window_end < self.removal_window_start:
            raise _bad(source, "parameter 'removals' must not be negative and the removal window "
                             "must not end before it starts")
        if self.scan_hold_limit <= 0 or self.body_hold_limit <= 0 or min(
                self.start_window, self.vi_start_window, self.reaction_window) < 0:
            raise _bad(source, "parameters 'scan_hold_limit' and 'body_hold_limit' must be positive, "
                             "'start_window', 'vi_start_window' and 'reaction_window' not negative")


@dataclass(frozen=True)
class BodySettings(SimLayout):
    """What every simulated robot body knows: how its base moves, the size of an assembly robot."""

    drive_speed: float = setting(0.15, "Base speed, m/s.")
    turn_speed: float = setting(1.0, "Base turning speed, rad/s.")
    decision_window: float = setting(
        2.0, "s of wall time the world's clock waits for the robot's next move: after a placement for its next "
        "goal (see tiling_sim/body_hold.py), after a scan its explorer stopped for until it drives on (see "
        "tiling_sim/scan_hold.py). Decisions cost no simulated time, however busy the host.")

    def check(self, source: str) -> None:
        super().check(source)
        if self.drive_speed <= 0 or self.turn_speed <= 0:
            raise _bad(source, "parameters 'drive_speed' and 'turn_speed' must be positive")
        if self.decision_window < 0:
            raise _bad(source, "parameter 'decision_window' must not be negative")


@dataclass(frozen=True)
class RobotBodySettings(BodySettings):
    """`sim_robot`: one assembly robot's body (its place_tile phases and their durations)."""

    locate_time: float = setting(2.0, "s to find a tile with the laser at its cache.")
    pick_time: float = setting(6.0, "s to pick a tile.")
    place_time: float = setting(10.0, "s to place a tile.")
    retreat_time: float = setting(2.0, "s to back off after placing.")
    approach_distance: float = setting(
        0.25, "m from a tile's centre to where the base stops to place it (further out if the base would "
        "stand on the structure).")
    base_clearance: float = setting(0.03, "m an assembly robot's base keeps from every tile of the structure.")
    room_wait_step: float = setting(
        1.0, "s of simulated time a robot waits before asking again for a spot another robot stands at.")
    room_patience: float = setting(
        60.0, "s of simulated time a robot waits for a spot before it goes anyway (two robots waiting for "
        "each other's spot).")

    def check(self, source: str) -> None:
        super().check(source)
        durations = (self.locate_time, self.pick_time, self.place_time, self.retreat_time, self.decision_window)
        if self.room_wait_step <= 0 or self.room_patience < 0:
            raise _bad(source, "parameter 'room_wait_step' must be positive, 'room_patience' not negative")
        if min(durations) < 0 or self.approach_distance < 0 or self.base_clearance < 0:
            raise _bad(source, "phase durations, 'decision_window', 'approach_distance' and "
                             "'base_clearance' must not be negative")

    def motion(self) -> MotionModel:
        return MotionModel(
            drive_speed=self.drive_speed, turn_speed=self.turn_speed, locate_time=self.locate_time,
            pick_time=self.pick_time, place_time=self.place_time, retreat_time=self.retreat_time,
            approach_distance=self.approach_distance, base_size=(self.robot_size[0], self.robot_size[1]),
            base_clearance=self.base_clearance,
        )


@dataclass(frozen=True)
class ViBodySettings(BodySettings):
    """`sim_vi`: the VI robot's body (its base and its Kinect)."""

    scan_period: float = setting(
        5.0, "s of simulated time between two Kinect scans while the VI robot stands; the world's clock waits "
        "for a slow vi_node rather than run past it.")
    verdict_timeout: float = setting(
        15.0, "The next scan waits for vi_node's verdict on the last one (/tile_states) or this many s of "
        "wall-clock time (a lost frame, a dead vi_node).")
    # the same names as vi_node's: the runner gives both nodes config/vi_node.yaml
    camera_xyz: list[float] = setting(  # noqa: RUF009 - a field() with a default_factory
        [0.08, 0.0, 0.55], "Pose of camera_link in the VI robot's base_link: x, y, z (m).")
    camera_rpy: list[float] = setting(  # noqa: RUF009 - a field() with a default_factory
        [0.0, 0.45, 0.0], "Pose of camera_link in base_link: roll, pitch, yaw (rad).")
    intrinsics: list[float] = setting(  # noqa: RUF009 - a field() with a default_factory
        [580.0, 580.0, 319.5, 239.5], "Kinect depth camera fx, fy, cx, cy (px).")
    intrinsics_size: list[int] = setting(  # noqa: RUF009 - a field() with a default_factory
        [640, 480], "Kinect depth image width, height (px).")
    robots_in_view: bool = setting(True, "The other robots (assembly and VI) appear in the Kinect's view (as boxes).")
    record_scans: str = setting(
        "", "Folder of a rosbag2 (MCAP) to write every Kinect frame to, with the camera's true pose, the other "
        "robots' and what truly lay in the world (truth.json), for `ros2 run vi_node classify`; empty: none.")

    def check(self, source: str) -> None:
        super().check(source)
        if self.scan_period <= 0 or self.verdict_timeout <= 0:
            raise _bad(source, "parameters 'scan_period' and 'verdict_timeout' must be positive")
        if len(self.camera_xyz) != 3 or len(self.camera_rpy) != 3:
            raise _bad(source, "parameters 'camera_xyz' and 'camera_rpy' need 3 numbers each")
        if len(self.intrinsics) != 4 or len(self.intrinsics_size) != 2 or min(self.intrinsics_size) <= 0:
            raise _bad(source, "parameters 'intrinsics' (fx, fy, cx, cy) and 'intrinsics_size' "
                             "(width, height) are incomplete")

    def motion(self) -> MotionModel:
        return MotionModel(drive_speed=self.drive_speed, turn_speed=self.turn_speed)


SETTINGS_OF_NODE = {"sim_world": WorldSettings, "sim_robot": RobotBodySettings, "sim_vi": ViBodySettings}


def _coerce(name: str, value: Any, default: Any, source: str) -> Any:
    """`value` as the type of `default` (an int is a float too; nothing else is converted)."""
    kinds = {bool: (bool,), int: (int,), float: (int, float), str: (str,)}
    if isinstance(default, list):
        kind = type(default[0]) if default else float
        if isinstance(value, list | tuple) and all(_is(v, kinds[kind]) for v in value):
            return [kind(v) for v in value]
    elif _is(value, kinds[type(default)]):
        result = type(default)(value)
        if not isinstance(result, float) or math.isfinite(result):
            return result
    raise _bad(source, f"parameter '{name}' has the wrong type (got {value!r}, expected like {default!r})")


def _bad(source: str, problem: str) -> ValueError:
    return ValueError(f"{source}: {problem}" if source else problem)


def _is(value: Any, kinds: tuple[type, ...]) -> bool:
    return isinstance(value, kinds) and (bool in kinds or not isinstance(value, bool))
