"""The planner's parameters: defaults, validation, and reading a ROS 2 parameter file without ROS.

The node declares these as ROS parameters; the `plan` command reads the same file format
(`config/planner_node.yaml`: `/**: ros__parameters: ...`), so both plan under the same time model.
`type_place_time` is a map from tile type to seconds (`type_place_time.square: 10.0` as a ROS
parameter); types not listed take `place_time`.
"""

from __future__ import annotations

import math
from array import array
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from planner_node.planner import (
    DEFAULT_IMPROVE_TIME_LIMIT,
    Method,
    PlanningError,
    check_robot_names,
    default_robot_names,
)
from tiling_assembly.time_model import TimeModel
from tiling_ros.parameters import setting

NODE_NAME = "planner_node"
_DEFAULT_TIMES = TimeModel()


class ParameterError(ValueError):
    """A parameter value or parameter file that cannot be used; the message is one line."""


@dataclass(frozen=True)
class PlannerParameters:
    """The planner's parameters with their defaults and descriptions (config/planner_node.yaml)."""

    structure_file: str = setting("", "Structure YAML file to build (the contract in DESIGN.md); required")
    num_robots: int = setting(2, "Number of assembly robots, named robot1..robotN, when robot_names is not set")
    robot_names: tuple[str, ...] = setting((), "Namespaces of the assembly robots; overrides num_robots")
    method: str = setting(
        Method.DEFAULT.value, "Planning method: default, paper (section 2.1 as published) or round-robin (baseline)")
    improve_time_limit: float = setting(
        DEFAULT_IMPROVE_TIME_LIMIT, "Seconds of local search the default method may spend (s)")
    help_neighbours: bool = setting(
        True, "Default method: a robot that would wait may place ready tiles of another robot (sooner finish; "
        "regions may then split). false keeps every robot to its own region")
    pick_time: float = setting(_DEFAULT_TIMES.pick_time, "Time to find and grasp a tile at its parts cache (s)")
    place_time: float = setting(
        _DEFAULT_TIMES.place_time, "Time to lower, release and retract a tile at the structure (s)")
    travel_speed: float = setting(
        _DEFAULT_TIMES.travel_speed, "Mean speed of a robot base between a cache and the structure (m/s)")
    cache_standoff: float = setting(
        _DEFAULT_TIMES.cache_standoff, "How far short of a parts cache a robot base stops, its arm's reach (m)")
    type_place_time: Mapping[str, float] = setting(
        {}, "Place time of a tile of this type (s); types not listed take place_time")
    cache_crowding: float = setting(
        _DEFAULT_TIMES.cache_crowding, "Time a pick costs for every robot beyond one per parts cache in use, "
        "as robots crowding a cache drive round it (s)")
    stop_crowding: float = setting(
        _DEFAULT_TIMES.stop_crowding, "Time a pick costs for every other robot times the share of the structure's "
        "stops a base at one of them overlaps, as robots meet beside the structure; the larger of this and the "
        "caches' crowding is charged (s)")
    approach_distance: float = setting(
        _DEFAULT_TIMES.approach_distance, "How far from a tile's centre a robot base stops to place it, its arm's "
        "reach; further out where the base would stand on the structure (m)")
    base_size: tuple[float, float] = setting(
        _DEFAULT_TIMES.base_size, "x and y size of a robot base's footprint, which stops clear of the structure (m)")
    base_clearance: float = setting(_DEFAULT_TIMES.base_clearance, "How far a robot base keeps from every tile (m)")
    robot_start_xy: tuple[float, ...] = setting(
        (0.0,), "x1, y1, x2, y2, ... where the robots stand when the build starts, in the structure's frame (m): "
        "each first drives to its first tile's cache. Fewer than 2 numbers: they start at those caches (the paper's)")

    def robots(self) -> list[str]:
        """robot_names when given, else robot1..robotN."""
        return list(self.robot_names) if self.robot_names else default_robot_names(self.num_robots)

    def planning_method(self) -> Method:
        return Method(self.method)

    def planning_options(self) -> dict[str, Any]:
        """Keyword arguments of `plan_assembly` / `replan_assembly` besides the time model."""
        return {
            "method": self.planning_method(),
            "improve_time_limit": self.improve_time_limit,
            "help_neighbours": self.help_neighbours,
        }

    def robot_starts(self) -> list[tuple[float, float]]:
        """(x, y) per robot from robot_start_xy; none when it has fewer than 2 numbers."""
        xy = self.robot_start_xy
        return [(xy[k], xy[k + 1]) for k in range(0, len(xy) - 1, 2)] if len(xy) >= 2 else []

    def time_model(self) -> TimeModel:
        return TimeModel(
            pick_time=self.pick_time,
            place_time=self.place_time,
            travel_speed=self.travel_speed,
            cache_standoff=self.cache_standoff,
            type_place_time=dict(self.type_place_time),
            cache_crowding=self.cache_crowding,
            stop_crowding=self.stop_crowding,
            approach_distance=self.approach_distance,
            base_size=self.base_size,
            base_clearance=self.base_clearance,
        )

    def validate(self) -> None:
        """Raise ParameterError naming the first bad value."""
        if isinstance(self.num_robots, bool) or not isinstance(self.num_robots, int) or self.num_robots < 1:
            raise ParameterError(f"num_robots must be a whole number >= 1, got {self.num_robots!r}")
        methods = [m.value for m in Method]
        if self.method not in methods:
            raise ParameterError(f"method must be one of {', '.join(methods)}, got {self.method!r}")
        if not (math.isfinite(self.improve_time_limit) and self.improve_time_limit >= 0):
            raise ParameterError(f"improve_time_limit must be >= 0 s, got {self.improve_time_limit!r}")
        if self.robot_names:
            try:
                check_robot_names(list(self.robot_names))
            except PlanningError as error:
                raise ParameterError(f"robot_names: {error}") from None
        xy = self.robot_start_xy
        if len(xy) >= 2 and (len(xy) % 2 or not all(math.isfinite(v) for v in xy)):
            raise ParameterError(f"robot_start_xy must be x, y pairs of numbers (m), got {list(xy)}")
        try:
            self.time_model()
        except (TypeError, ValueError) as error:
            raise ParameterError(str(error)) from None


_FIELDS = {
    "structure_file": str,
    "num_robots": int,
    "robot_names": list,
    "method": str,
    "improve_time_limit": float,
    "help_neighbours": bool,
    "pick_time": float,
    "place_time": float,
    "travel_speed": float,
    "cache_standoff": float,
    "cache_crowding": float,
    "stop_crowding": float,
    "approach_distance": float,
    "base_size": tuple,
    "base_clearance": float,
    "robot_start_xy": tuple,
}


def _flatten(values: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    flat: dict[str, Any] = {}
    for key, value in values.items():
        name = f"{prefix}{key}"
        if isinstance(value, Mapping):
            flat.update(_flatten(value, f"{name}."))
        else:
            flat[name] = value
    return flat


def _convert(name: str, value: Any, kind: type) -> Any:
    if kind is float and isinstance(value, (int, float)) and not isinstance(value, bool):
        return float(value)
    if kind is int and isinstance(value, int) and not isinstance(value, bool):
        return value
    if kind is bool and isinstance(value, bool):
        return value
    if kind is str and isinstance(value, str):
        return value
    if kind is list and isinstance(value, list) and all(isinstance(v, str) for v in value):
        return tuple(value)
    if kind is tuple and isinstance(value, Sequence | array) and all(
            isinstance(v, int | float) and not isinstance(v, bool) for v in value):
        return tuple(float(v) for v in value)
    wanted = {
        float: "a number",
        int: "a whole number",
        bool: "true or false",
        str: "a string",
        list: "a list of strings",
        tuple: "a list of numbers",
    }[kind]
    raise ParameterError(f"{name} must be {wanted}, got {value!r}")


def parameters_from_values(values: Mapping[str, Any]) -> tuple[PlannerParameters, list[str]]:
    """Parameters from flat ROS parameter values; also returns the names it did not know."""
    known: dict[str, Any] = {}
    per_type: dict[str, float] = {}
    unknown = []
    for name, value in values.items():
        if name in _FIELDS:
            known[name] = _convert(name, value, _FIELDS[name])
        elif name.startswith("type_place_time."):
            per_type[name.split(".", 1)[1]] = _convert(name, value, float)
        elif name != "use_sim_time":
            unknown.append(name)
    parameters = PlannerParameters(**known, type_place_time=per_type)
    parameters.validate()
    return parameters, unknown


def read_parameter_file(path: str | Path) -> tuple[PlannerParameters, list[str]]:
    """Read the planner's entries of a ROS 2 parameter file (see the module docstring)."""
    try:
        document = yaml.safe_load(Path(path).read_text(encoding="utf-8"))
    except OSError as error:
        raise ParameterError(f"{path}: cannot read the file: {error.strerror or error}") from None
    except (yaml.YAMLError, UnicodeDecodeError) as error:
        first_line = str(error).splitlines()[0]
        raise ParameterError(f"{path}: not a valid YAML parameter file ({first_line})") from None
    if not isinstance(document, Mapping):
        raise ParameterError(f"{path}: a parameter file maps node names to 'ros__parameters'")
    values: dict[str, Any] = {}
    matched = False
    for node, entry in document.items():
        name = str(node).lstrip("/")
        if name not in ("**", NODE_NAME) and not name.endswith(f"/{NODE_NAME}"):
            continue
        if not isinstance(entry, Mapping) or not isinstance(entry.get("ros__parameters"), Mapping):
            raise ParameterError(f"{path}: entry '{node}' needs a 'ros__parameters' mapping")
        values.update(_flatten(entry["ros__parameters"]))
        matched = True
    if not matched:
        raise ParameterError(f"{path}: no '/**' or '{NODE_NAME}' entry with 'ros__parameters'")
    try:
        return parameters_from_values(values)
    except ParameterError as error:
        raise ParameterError(f"{path}: {error}") from None
