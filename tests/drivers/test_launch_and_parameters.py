"""Launch files of every package and the parameter files of the M3 and scanning robots.

The launch files are checked statically here, without the `launch` package (not on PyPI): they
compile, use only the launch/launch_ros API, and name executables, parameter files and launch files
the workspace installs. The team's nodes come from config/team.yaml through
tiling_assembly.team_launch (tests/test_team_file.py checks that file against the workspace and the
experiment). tests/test_real_launch.py runs them under the real `ros2 launch` where it is
installed. The parameter files are checked against the nodes themselves: every key is a parameter
the node declares (a misspelt key would otherwise be silently ignored by ROS).
"""

from __future__ import annotations

import ast
import configparser
import re
from pathlib import Path

import pytest
import yaml
from processes import REPO
from ros_probe import shared_probe

PACKAGE = REPO / "hardware_drivers"
INSTALL = REPO / "install"
LAUNCH_FILES = sorted(REPO.glob("*/launch/*.launch.py"))
ROBOT_LAUNCH_FILES = [p for p in LAUNCH_FILES if p.name != "team.launch.py"]  # nodes in a robot's namespace
TEAM_LAUNCH = REPO / "tiling_assembly" / "tiling_assembly" / "team_launch.py"
# the value types launch_ros' ParameterValue accepts (a bare `list` fails: "Unrecognized data type")
SCALAR_TYPES = {"int", "float", "bool", "str"}


def entry_points() -> set[str]:
    setup = (PACKAGE / "setup.py").read_text()
    return set(re.findall(r'"(\w+) = hardware_drivers\.[\w.]+:\w+"', setup))


def test_every_package_has_its_launch_files() -> None:
    assert {f"{p.parent.parent.name}/{p.name}" for p in LAUNCH_FILES} == {
        "assembly_node/assembly_robot.launch.py", "auction_node/team.launch.py",
        "hardware_drivers/m3_robot.launch.py", "hardware_drivers/vi_robot.launch.py",
        "vi_node/inspection.launch.py",
    }


def calls(tree: ast.AST, name: str) -> list[ast.Call]:
    return [n for n in ast.walk(tree) if isinstance(n, ast.Call) and getattr(n.func, "id", "") == name]


def keywords(call: ast.Call) -> dict[str, ast.expr]:
    return {k.arg: k.value for k in call.keywords if k.arg is not None}


def shared_packages(tree: ast.AST) -> set[str]:
    """The packages whose share directory the launch file looks into (FindPackageShare("...")."""
    return {c.args[0].value for c in calls(tree, "FindPackageShare") if isinstance(c.args[0], ast.Constant)}


def installed_share_files(packages: set[str], folder: str) -> set[str]:
    return {p.name for package in packages for p in (INSTALL / package / "share" / package / folder).glob("*")}


def parse(path: Path) -> ast.Module:
    tree = ast.parse(path.read_text(), str(path))
    compile(tree, str(path), "exec")
    return tree


@pytest.mark.parametrize("path", LAUNCH_FILES, ids=lambda p: p.name)
def test_launch_file_compiles_and_references_what_the_workspace_installs(path: Path) -> None:
    tree = parse(path)
    modules = {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
    assert {m.split(".")[0] for m in modules} <= {"launch", "launch_ros", "tiling_assembly"}
    assert {m for m in modules if m.startswith("tiling_assembly")} <= {"tiling_assembly.team_launch"}
    assert "generate_launch_description" in [n.name for n in tree.body if isinstance(n, ast.FunctionDef)]
    package = path.parent.parent.name
    assert (INSTALL / package / "share" / package / "launch" / path.name).exists()
    nodes = calls(tree, "Node")
    assert nodes or calls(tree, "role_nodes")
    for node in nodes:
        arguments = keywords(node)
        assert {"package", "executable", "name"} <= set(arguments)
        if isinstance(arguments["package"], ast.Constant):  # not a user's driver named by an argument
            node_package, executable = arguments["package"].value, arguments["executable"].value
            assert (INSTALL / node_package / "lib" / node_package / executable).is_file(), executable
    constants = {c.value for c in ast.walk(tree) if isinstance(c, ast.Constant) and isinstance(c.value, str)}
    packages = shared_packages(tree)
    assert {c for c in constants if c.endswith(".yaml")} <= installed_share_files(packages, "config")
    assert {c for c in constants if c.endswith(".launch.py")} <= installed_share_files(packages, "launch")


@pytest.mark.parametrize("path", ROBOT_LAUNCH_FILES, ids=lambda p: p.name)
def test_robot_nodes_run_in_the_robots_namespace(path: Path) -> None:
    tree = parse(path)
    for node in calls(tree, "Node"):
        assert "namespace" in keywords(node)
    for team_nodes in calls(tree, "role_nodes"):
        assert len(team_nodes.args) == 2, "the robot's namespace argument is not passed on"


def value_type_launch_accepts(value_type: ast.expr) -> bool:
    """int, float, bool, str or a list of one of them (list[str] or List[str])."""
    if isinstance(value_type, ast.Name):
        return value_type.id in SCALAR_TYPES
    return (isinstance(value_type, ast.Subscript) and getattr(value_type.value, "id", "") in {"list", "List"}
            and getattr(value_type.slice, "id", "") in SCALAR_TYPES)


@pytest.mark.parametrize("path", [*LAUNCH_FILES, TEAM_LAUNCH], ids=lambda p: p.name)
def test_typed_parameter_values_use_types_launch_accepts(path: Path) -> None:
    for value in calls(parse(path), "ParameterValue"):
        value_type = keywords(value).get("value_type")
        assert value_type is None or value_type_launch_accepts(value_type), ast.unparse(value)


def test_hardware_drivers_launch_files_start_its_own_nodes() -> None:
    installed = entry_points()
    for path in (PACKAGE / "launch").glob("*.launch.py"):
        ours = [keywords(n) for n in calls(parse(path), "Node")
                if isinstance(keywords(n)["package"], ast.Constant)]
        assert len(ours) >= 2
        assert all(k["package"].value == "hardware_drivers" and k["executable"].value in installed for k in ours)


def test_m3_launch_remaps_the_overhead_pose_and_vi_launch_the_kinect() -> None:
    m3 = (PACKAGE / "launch" / "m3_robot.launch.py").read_text()
    vi = (PACKAGE / "launch" / "vi_robot.launch.py").read_text()
    assert '("overhead_pose", LaunchConfiguration("overhead_pose_topic"))' in m3
    assert '"camera/depth/points")' in vi and "/vi/camera/depth/points" in vi
    assert "/vi/overhead_pose" in vi and "/robotK/overhead_pose" in vi


def test_scripts_install_where_ros2_run_finds_them() -> None:
    config = configparser.ConfigParser()
    config.read(PACKAGE / "setup.cfg")
    assert config["install"]["install_scripts"] == "$base/lib/hardware_drivers"
    contract = {"create_base", "crustcrawler_arm", "hokuyo_urg", "m3_robot"}  # DESIGN.md
    assert contract <= entry_points()
    installed = REPO / "install" / "hardware_drivers" / "lib" / "hardware_drivers"
    assert entry_points() <= {p.name for p in installed.iterdir()}


def flatten(values: dict, prefix: str = "") -> set[str]:
    keys: set[str] = set()
    for key, value in values.items():
        if isinstance(value, dict):
            keys |= flatten(value, f"{prefix}{key}.")
        else:
            keys.add(f"{prefix}{key}")
    return keys


def sections() -> dict[str, set[str]]:
    drivers = yaml.safe_load((REPO / "config" / "hardware_drivers.yaml").read_text())
    arm = yaml.safe_load((REPO / "config" / "crustcrawler_arm.yaml").read_text())
    assert set(arm) == {"/**"}  # works in any namespace, for every node that loads it
    found = {key.removeprefix("/**/"): flatten(value["ros__parameters"]) for key, value in drivers.items()}
    found["arm description"] = flatten(arm["/**"]["ros__parameters"])
    return found


def declared_parameters(node_class: type) -> set[str]:
    """The parameters a node declares when started with both parameter files, as the launch files do."""
    shared_probe()  # rclpy is initialised
    files = [str(REPO / "config" / name) for name in ("hardware_drivers.yaml", "crustcrawler_arm.yaml")]
    node = node_class(cli_args=["--ros-args", *[a for f in files for a in ("--params-file", f)],
                                "-p", "port:=/nonexistent/port"])
    try:
        return set(node._parameters)
    finally:
        if hasattr(node, "shutdown"):
            node.shutdown()
        node.destroy_node()


def test_every_parameter_in_the_files_is_declared_by_its_node() -> None:
    from hardware_drivers.base_navigator_node import BaseNavigatorNode
    from hardware_drivers.create_base_node import CreateBaseNode
    from hardware_drivers.crustcrawler_arm_node import CrustCrawlerArmNode
    from hardware_drivers.hokuyo_urg_node import HokuyoUrgNode
    from hardware_drivers.m3_robot_node import M3RobotNode

    files = sections()
    assert set(files) == {"create_base", "crustcrawler_arm", "hokuyo_urg", "m3_robot", "base_navigator",
                          "arm description"}
    classes = {"create_base": CreateBaseNode, "crustcrawler_arm": CrustCrawlerArmNode,
               "hokuyo_urg": HokuyoUrgNode, "m3_robot": M3RobotNode, "base_navigator": BaseNavigatorNode}
    for name, node_class in classes.items():
        declared = declared_parameters(node_class)
        assert files[name] <= declared, f"{name}: undeclared keys {sorted(files[name] - declared)}"
        if name == "crustcrawler_arm":
            assert files["arm description"] <= declared
        if name == "m3_robot":
            servo_only = {"servo_ids", "joint_offsets", "joint_directions"}
            assert files["arm description"] - servo_only <= declared
