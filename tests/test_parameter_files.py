"""The parameter files of config/ and the nodes' settings dataclasses agree.

Every node declares its parameters from frozen settings dataclasses (`tiling_ros.parameters`),
which hold the defaults. For each section of a file in config/ and the nodes that are given it
(config/team.yaml for the team's nodes and their simulated bodies, the hardware launch files for
the drivers, the experiment runner for `sim_world`):

* every parameter in the section is a field of a dataclass of a node given it, of a compatible type
  (a float is not an int: most nodes let ROS enforce the default's type);
* every field of a node's dataclasses is documented in one of its files (a key, or a commented-out
  `# name:` line), unless `UNDOCUMENTED` says why not;
* a value that differs from the dataclass's default is a deliberate override listed in `OVERRIDES`.
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import pytest
import yaml

from assembly_node.assembly_node import AssemblySettings
from auction_node.auction_node import AuctionSettings
from hardware_drivers.base_navigator_node import BaseNavigatorSettings
from hardware_drivers.create_base_node import CreateBaseSettings
from hardware_drivers.crustcrawler_arm_node import ArmDescriptionSettings, CrustCrawlerArmSettings
from hardware_drivers.hokuyo_urg_node import HokuyoUrgSettings
from hardware_drivers.m3_robot_node import M3RobotSettings
from planner_node.parameters import PlannerParameters
from tiling_sim.sim_settings import RobotBodySettings, ViBodySettings, WorldSettings
from vi_node.explorer_node import ExplorerSettings
from vi_node.inspection_settings import InspectionSettings

CONFIG = Path(__file__).resolve().parent.parent / "config"

# executable -> the settings dataclasses it declares its parameters from
SETTINGS: dict[str, tuple[type, ...]] = {
    "assembly_node": (AssemblySettings,),
    "auction_node": (AuctionSettings,),
    "planner_node": (PlannerParameters,),
    "vi_node": (InspectionSettings,),
    "vi_explorer": (ExplorerSettings,),
    "sim_world": (WorldSettings,),
    "sim_robot": (RobotBodySettings,),
    "sim_vi": (ViBodySettings,),
    "create_base": (CreateBaseSettings,),
    "hokuyo_urg": (HokuyoUrgSettings,),
    "base_navigator": (BaseNavigatorSettings,),
    "crustcrawler_arm": (ArmDescriptionSettings, CrustCrawlerArmSettings),
    "m3_robot": (ArmDescriptionSettings, M3RobotSettings),
}

# the parameter files of the nodes config/team.yaml does not list
OTHER_FILES: dict[str, list[str]] = {
    "sim_world": ["tiling_sim.yaml"],  # tiling_sim/experiment.py (world_command)
    # hardware_drivers/launch/m3_robot.launch.py and vi_robot.launch.py
    "create_base": ["hardware_drivers.yaml"],
    "hokuyo_urg": ["hardware_drivers.yaml"],
    "base_navigator": ["hardware_drivers.yaml"],
    "crustcrawler_arm": ["hardware_drivers.yaml", "crustcrawler_arm.yaml"],
    "m3_robot": ["hardware_drivers.yaml", "crustcrawler_arm.yaml"],
}

# parameters whose names are made from other parameters' values: not dataclass fields
DYNAMIC = {
    "named_poses": "named_poses.<name>: one per name of named_pose_names, an angle per arm joint",
    "type_place_time": "type_place_time.<type>: one per tile type of the structure (the field holds the map)",
}

# (executable, field) -> why its files do not document it
UNDOCUMENTED: dict[tuple[str, str], str] = {
    **{("vi_explorer", name): "config/vi_node.yaml is also `classify --params`'s file, which refuses names "
       "that are not vi_node's; the explorer's own settings keep their defaults"
       for name in ("viewpoint_radii", "viewpoints_per_ring", "settle_time", "scan_timeout", "travel_cost",
                    "claim_clearance", "shared_weight", "claim_age", "idle_wait")},
    **{(node, name): "given by the experiment runner on the command line (the trial's structure, team and seed)"
       for node in ("sim_world", "sim_robot", "sim_vi")
       for name in ("structure_file", "robot_names", "vi_robot_names", "seed")
       if (node, name) != ("sim_vi", "structure_file")},  # sim_vi's file vi_node.yaml names it (vi_node's)
    **{("sim_world", name): "given by the experiment runner per trial (faults, start signal)"
       for name in ("removals", "removal_window_start", "removal_window_end", "wait_for_start", "misplacements",
                    "wrong_tiles")},
    **{(node, "robot_size"): "the robots' box; sim_vi and vi_node read it from config/vi_node.yaml, where it is "
       "vi_node's, and sim_robot and sim_world are not given that file" for node in ("sim_robot", "sim_world")},
    ("sim_vi", "robots_in_view"): "a switch for tests of the simulated Kinect; the experiment always shows the robots",
}

# (file, parameter) -> why the file's value is not the dataclass's default
OVERRIDES: dict[tuple[str, str], str] = {
    ("tiling_sim.yaml", "robot_start_xy"): "the paper's two robots start next to the caches (the default, a "
    "single number, spreads any team on a circle; the runner falls back to it for other team sizes)",
    ("crustcrawler_arm.yaml", "joint_lower_limits"): "the real arm's joint limits (the default: +-2.6 rad each)",
    ("crustcrawler_arm.yaml", "joint_upper_limits"): "the real arm's joint limits (the default: +-2.6 rad each)",
    ("crustcrawler_arm.yaml", "joint_max_velocities"): "the real servos' speeds (the default: 1 rad/s each)",
    ("crustcrawler_arm.yaml", "named_pose_names"): "the real arm has a carry pose too (m3_robot holds it while "
    "driving)",
}


def team_files() -> dict[str, list[str]]:
    """executable -> its parameter files, from config/team.yaml (as the launch files and the experiment)."""
    team = yaml.safe_load((CONFIG / "team.yaml").read_text())
    files: dict[str, list[str]] = {}
    for role in team.values():
        for node in [*role.get("nodes", []), *role.get("simulated_by", [])]:
            files[node["executable"]] = list(node.get("parameters", []))
    return files


def files_of() -> dict[str, list[str]]:
    return {**team_files(), **OTHER_FILES}


def flatten(values: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    flat: dict[str, Any] = {}
    for key, value in values.items():
        if isinstance(value, Mapping):
            flat.update(flatten(value, f"{prefix}{key}."))
        else:
            flat[f"{prefix}{key}"] = value
    return flat


def sections_for(node: str, file: str) -> dict[str, dict[str, Any]]:
    """The sections of `file` that apply to `node` (`/**` and `/**/<node>`), with their flat values."""
    document = yaml.safe_load((CONFIG / file).read_text())
    return {key: flatten(entry["ros__parameters"]) for key, entry in document.items()
            if key == "/**" or key.endswith(f"/{node}")}


def fields_of(node: str) -> dict[str, dataclasses.Field[Any]]:
    return {f.name: f for cls in SETTINGS[node] for f in dataclasses.fields(cls)}


def default_of(node: str, name: str) -> Any:
    for cls in SETTINGS[node]:
        if name in {f.name for f in dataclasses.fields(cls)}:
            return getattr(cls(), name)
    raise KeyError(name)


def compatible(value: Any, default: Any) -> bool:
    """Whether a file's value has the type of the default (lists: of its items' type)."""
    def same_kind(item: Any, like: Any) -> bool:
        if isinstance(like, bool) or isinstance(item, bool):
            return isinstance(item, bool) and isinstance(like, bool)
        return isinstance(item, type(like))

    if isinstance(default, list | tuple):
        return isinstance(value, list) and (not default or all(same_kind(v, default[0]) for v in value))
    return same_kind(value, default)


def equal(value: Any, default: Any) -> bool:
    if isinstance(default, list | tuple):
        return isinstance(value, list) and len(value) == len(default) and all(map(equal, value, default))
    if isinstance(default, float):
        return math.isclose(value, default, rel_tol=1e-12, abs_tol=1e-12)
    return bool(value == default)


def documented_names(file: str) -> set[str]:
    """Keys of the file, and keys of commented-out lines (`# robot_names: [...]`)."""
    return set(re.findall(r"^\s*#?\s*([A-Za-z_][A-Za-z0-9_]*):", (CONFIG / file).read_text(), re.MULTILINE))


def test_every_node_of_the_team_file_has_settings() -> None:
    assert set(team_files()) <= set(SETTINGS)
    assert set(files_of()) == set(SETTINGS)


@pytest.mark.parametrize("node", sorted(SETTINGS))
def test_every_parameter_in_a_nodes_files_is_a_field_of_its_settings(node: str) -> None:
    """Of the sections a node is given, those meant for it; `/**` sections shared with other nodes are
    checked for the names some node that reads them declares."""
    readers = files_of()
    fields = fields_of(node)
    for file in readers[node]:
        for key, values in sections_for(node, file).items():
            sharing = [other for other, files in readers.items()
                       if file in files and key in sections_for(other, file)]
            known = {name for other in sharing for name in fields_of(other)}
            for name, value in values.items():
                base = name.split(".", 1)[0]
                if base in DYNAMIC:
                    continue
                assert name in known, f"{file} {key}: {name} is no parameter of {', '.join(sharing)}"
                if name in fields:
                    default = default_of(node, name)
                    assert compatible(value, default), (
                        f"{file} {key}: {name} = {value!r} does not have the type of {node}'s default {default!r}")


@pytest.mark.parametrize("node", sorted(SETTINGS))
def test_every_field_is_documented_in_a_file_of_its_node(node: str) -> None:
    documented = set().union(*(documented_names(file) for file in files_of()[node]))
    missing = [name for name in fields_of(node) if name not in documented and (node, name) not in UNDOCUMENTED]
    assert not missing, f"{node}: settings no parameter file of it documents: {missing}"
    stale = [name for (owner, name) in UNDOCUMENTED if owner == node and name in documented]
    assert not stale, f"{node}: listed as undocumented but documented: {stale}"


@pytest.mark.parametrize("node", sorted(SETTINGS))
def test_a_value_other_than_the_default_is_a_deliberate_override(node: str) -> None:
    fields = fields_of(node)
    for file in files_of()[node]:
        for key, values in sections_for(node, file).items():
            for name, value in values.items():
                if name not in fields:
                    continue
                differs = not equal(value, default_of(node, name))
                assert differs == ((file, name) in OVERRIDES), (
                    f"{file} {key}: {name} = {value!r}, {node}'s default {default_of(node, name)!r}: "
                    + ("not listed in OVERRIDES" if differs else "listed in OVERRIDES but equal"))


def test_every_field_has_a_description() -> None:
    for node, classes in SETTINGS.items():
        for cls in classes:
            for f in dataclasses.fields(cls):
                assert f.metadata.get("description"), f"{node}: {cls.__name__}.{f.name} has no description"
