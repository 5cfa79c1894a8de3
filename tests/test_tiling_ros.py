"""tiling_ros: stamps, point clouds as messages, and settings dataclasses declared as parameters."""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np
import pytest
import rclpy
from builtin_interfaces.msg import Duration
from rclpy.exceptions import InvalidParameterTypeException
from rclpy.node import Node
from rclpy.serialization import deserialize_message, serialize_message
from ros_helpers.isolated_domains import fresh_domain
from sensor_msgs.msg import PointCloud2
from std_msgs.msg import Header

from tiling_ros.parameters import declare_settings, setting, setting_description, setting_names
from tiling_ros.point_clouds import CloudError, cloud_from_msg, cloud_to_msg
from tiling_ros.stamps import (
    is_zero,
    stamp_from_nanoseconds,
    stamp_from_seconds,
    stamp_to_nanoseconds,
    stamp_to_seconds,
)


# --- stamps -----------------------------------------------------------------------------------------
@pytest.mark.parametrize("nanoseconds", [0, 1, 999_999_999, 10**9, 1_732_000_000_123_456_789])
def test_a_stamp_keeps_its_nanoseconds(nanoseconds: int) -> None:
    stamp = stamp_from_nanoseconds(nanoseconds)
    assert 0 <= stamp.nanosec < 10**9
    assert stamp_to_nanoseconds(stamp) == nanoseconds
    assert is_zero(stamp) == (nanoseconds == 0)


@pytest.mark.parametrize("seconds", [0.0, 0.02, 12.345678901, 86_400.5])
def test_a_stamp_keeps_its_seconds_to_the_nanosecond(seconds: float) -> None:
    stamp = stamp_from_seconds(seconds)
    assert stamp_to_seconds(stamp) == pytest.approx(seconds, abs=1e-9)
    assert stamp_to_nanoseconds(stamp) == round(seconds * 1e9)


def test_a_duration_reads_like_a_stamp() -> None:
    assert stamp_to_seconds(Duration(sec=2, nanosec=500_000_000)) == 2.5


# --- point clouds -----------------------------------------------------------------------------------
def _cloud(height: int = 6, width: int = 8) -> np.ndarray:
    rng = np.random.default_rng(3)
    cloud = rng.uniform(-2.0, 2.0, (height, width, 3)).astype(np.float32)
    cloud[1, 2] = np.nan  # no return
    return cloud


def test_a_cloud_comes_back_from_its_message() -> None:
    cloud = _cloud()
    header = Header(frame_id="camera_depth_optical_frame")
    header.stamp = stamp_from_seconds(7.25)
    msg = cloud_to_msg(cloud, header)
    assert isinstance(msg, PointCloud2)
    assert (msg.height, msg.width, msg.point_step, msg.row_step) == (6, 8, 12, 96)
    assert msg.header.frame_id == "camera_depth_optical_frame" and stamp_to_seconds(msg.header.stamp) == 7.25
    wire = deserialize_message(serialize_message(msg), PointCloud2)
    assert np.array_equal(cloud_from_msg(wire), cloud, equal_nan=True)


def test_a_corrupt_cloud_is_refused_in_one_line() -> None:
    msg = cloud_to_msg(_cloud(), Header())
    truncated = deserialize_message(serialize_message(msg), PointCloud2)
    truncated.data = bytes(msg.data)[:100]
    with pytest.raises(CloudError, match="data holds 100 bytes") as error:
        cloud_from_msg(truncated)
    assert "\n" not in str(error.value)
    no_z = deserialize_message(serialize_message(msg), PointCloud2)
    no_z.fields = no_z.fields[:2]
    with pytest.raises(CloudError, match="cloud has no z field"):
        cloud_from_msg(no_z)
    with pytest.raises(CloudError, match="expected an \\(H, W, 3\\) cloud"):
        cloud_to_msg(np.zeros((4, 3), dtype=np.float32), Header())


# --- parameters -------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ExampleSettings:
    speed: float = setting(0.2, "m/s, driving speed")
    name: str = setting("robot1", "the robot's name")
    retries: int = setting(3, "attempts before giving up")
    enabled: bool = setting(True, "whether it runs")
    mount: list[float] = setting([0.1, 0.0, 0.07], "x, y, z of the mount (m)")  # noqa: RUF009


@pytest.fixture
def context() -> rclpy.Context:
    return fresh_domain().context


def _node(context: rclpy.Context, *overrides: str) -> Node:
    arguments = ["--ros-args", *[a for o in overrides for a in ("-p", o)]]
    return rclpy.create_node("settings_example", context=context, cli_args=arguments)


def test_a_settings_class_holds_its_defaults_and_descriptions() -> None:
    assert setting_names(ExampleSettings) == ["speed", "name", "retries", "enabled", "mount"]
    assert setting_description(ExampleSettings, "mount") == "x, y, z of the mount (m)"
    first, second = ExampleSettings(), ExampleSettings()
    assert first.mount == [0.1, 0.0, 0.07] and first.mount is not second.mount


def test_settings_are_declared_with_their_descriptions(context: rclpy.Context) -> None:
    node = _node(context, "speed:=0.5", "mount:=[1.0, 2.0, 3.0]")
    try:
        settings = declare_settings(node, ExampleSettings)
        assert settings == replace(ExampleSettings(), speed=0.5, mount=[1.0, 2.0, 3.0])
        for name in setting_names(ExampleSettings):
            descriptor = node.describe_parameter(name)
            assert descriptor.description == setting_description(ExampleSettings, name)
            assert not descriptor.dynamic_typing
    finally:
        node.destroy_node()


def test_a_value_of_another_type_is_refused_unless_typing_is_dynamic(context: rclpy.Context) -> None:
    node = _node(context, "retries:=2.5")
    try:
        with pytest.raises(InvalidParameterTypeException):
            declare_settings(node, ExampleSettings)
    finally:
        node.destroy_node()
    node = _node(context, "retries:=2.5")
    try:
        checked: list[dict[str, object]] = []
        settings = declare_settings(node, ExampleSettings, dynamic_typing=True,
                                    build=lambda values: checked.append(dict(values)) or ExampleSettings())
        assert checked[0]["retries"] == 2.5 and settings == ExampleSettings()
        assert node.describe_parameter("retries").dynamic_typing
    finally:
        node.destroy_node()


def test_a_busy_reader_hears_every_robots_heartbeat(context: rclpy.Context) -> None:
    """/robot_status has no key: its writers share one history at the reader. Eight robots'
    heartbeats arriving between two takes of a busy reader must all be there, not only the last."""
    from rclpy.executors import SingleThreadedExecutor

    from tiling_assembly_msgs.msg import RobotStatus
    from tiling_ros import team_topics as topics

    writers = rclpy.create_node("robots", context=context)
    reader = rclpy.create_node("auctioneer", context=context)
    heard: list[str] = []
    try:
        publishers = [topics.ROBOT_STATUS.publisher(writers) for _ in range(8)]
        topics.ROBOT_STATUS.subscribe(reader, lambda msg: heard.append(msg.robot_name))
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(reader)
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline and reader.count_publishers("/robot_status") < 8:
            executor.spin_once(timeout_sec=0.05)
        for _ in range(5):  # the reader takes nothing while every robot sends one heartbeat
            for k, publisher in enumerate(publishers):
                publisher.publish(RobotStatus(robot_name=f"robot{k + 1}"))
            time.sleep(0.1)
            for _ in range(20):
                executor.spin_once(timeout_sec=0.0)
        assert {name: heard.count(name) for name in set(heard)} == {f"robot{k + 1}": 5 for k in range(8)}
    finally:
        writers.destroy_node()
        reader.destroy_node()
