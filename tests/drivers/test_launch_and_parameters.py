"""Launch files and parameter files of the M3 and scanning robots.

There is no `launch` package on this machine, so the launch files are checked statically: they
compile, use only the launch/launch_ros API, name executables this package installs and parameter
files it installs. The parameter files are checked against the nodes themselves: every key is a
parameter the node declares (a misspelt key would otherwise be silently ignored by ROS).
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
LAUNCH_FILES = sorted((PACKAGE / "launch").glob("*.launch.py"))


def entry_points() -> set[str]:
    setup = (PACKAGE / "setup.py").read_text()
    return set(re.findall(r'"(\w+) = hardware_drivers\.[\w.]+:main"', setup))


def test_both_robots_have_a_launch_file() -> None:
    assert {p.name for p in LAUNCH_FILES} == {"m3_robot.launch.py", "vi_robot.launch.py"}


@pytest.mark.parametrize("path", LAUNCH_FILES, ids=lambda p: p.name)
def test_launch_file_compiles_and_references_what_the_package_installs(path: Path) -> None:
    tree = ast.parse(path.read_text(), str(path))
    compile(tree, str(path), "exec")
    modules = {n.module.split(".")[0] for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
    assert modules <= {"launch", "launch_ros"}
    functions = [n.name for n in tree.body if isinstance(n, ast.FunctionDef)]
    assert "generate_launch_description" in functions
    nodes = [n for n in ast.walk(tree) if isinstance(n, ast.Call) and getattr(n.func, "id", "") == "Node"]
    assert nodes
    installed = entry_points()
    ours = 0
    for node in nodes:
        keywords = {k.arg: k.value for k in node.keywords}
        assert {"package", "executable", "namespace"} <= set(keywords)
        package = keywords["package"]
        if isinstance(package, ast.Constant):
            assert package.value == "hardware_drivers"
            assert keywords["executable"].value in installed
            ours += 1
    assert ours >= 2
    constants = [c.value for c in ast.walk(tree) if isinstance(c, ast.Constant)]
    yaml_files = {c for c in constants if str(c).endswith(".yaml")}
    assert yaml_files
    installed_config = re.findall(r'"\.\./config/([\w.]+)"', (PACKAGE / "setup.py").read_text())
    for name in yaml_files:
        assert (REPO / "config" / name).is_file() and name in installed_config


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
