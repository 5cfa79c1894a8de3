"""`create_base`: the iRobot Create base of an M3 or scanning robot (paper section 3.1) as a node.

    ros2 run hardware_drivers create_base --ros-args -r __ns:=/robot1 -p port:=/dev/ttyUSB0

Subscribes ``cmd_vel`` (geometry_msgs/Twist: linear.x m/s, angular.z rad/s; clamped to the
limits; the wheels stop when commands stop for ``watchdog_timeout``). Publishes ``odom``
(nav_msgs/Odometry, frame ``odom`` -> ``base_link``), ``battery`` (sensor_msgs/BatteryState),
``bumper`` and ``wheel_drop`` (std_msgs/Bool, on change and once a second) and ``/diagnostics``.
A bump or wheel drop stops the wheels (see ``create_driver``). The port may be missing at start
or vanish: the node keeps running, says so once, and reconnects when the robot is back.

The odom -> base_link transform is not broadcast: the PyPI build of ROS this project runs on has no
tf2; where tf2 is installed, run a transform broadcaster from ``odom`` if tools need it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from rclpy.time import Time
from sensor_msgs.msg import BatteryState
from std_msgs.msg import Bool

from hardware_drivers.create_driver import CreateConfig, CreateDriver, CreateState
from hardware_drivers.node_support import (
    build_driver,
    device_diagnostics,
    monotonic_offset,
    require,
    require_positive,
    run_node,
)
from tiling_ros.parameters import declare_settings, setting
from tiling_ros.qos import SENSOR_PUBLISHER

_CREATE = CreateConfig(port="/dev/ttyUSB0")


@dataclass(frozen=True)
class CreateBaseSettings:
    """The parameters of create_base (config/hardware_drivers.yaml), with their defaults."""

    port: str = setting(_CREATE.port, "serial device of the Create (a pty path works)")
    baud: int = setting(_CREATE.baud, "baud rate: 57600 for a Create 1, 115200 for a Create 2")
    model: str = setting(_CREATE.model, "create1 or create2 (wheel geometry, stream contents)")
    mode: str = setting(_CREATE.mode, "OI mode: safe (the robot stops at cliffs and drops) or full")
    odometry: str = setting(
        _CREATE.odometry, "distance_angle (Create 1 packets 19/20) or encoders (Create 2 packets 43/44)")
    max_linear: float = setting(_CREATE.max_linear, "m/s, largest forward speed accepted from cmd_vel")
    max_angular: float = setting(_CREATE.max_angular, "rad/s, largest turn rate accepted from cmd_vel")
    watchdog_timeout: float = setting(_CREATE.watchdog_timeout, "s without cmd_vel before the wheels stop")
    stream_timeout: float = setting(_CREATE.stream_timeout, "s without sensor data before reconnecting")
    publish_rate: float = setting(50.0, "Hz, odometry rate (the Create streams at 66 Hz)")
    odom_frame: str = setting("odom", "frame of the odometry pose")
    base_frame: str = setting("base_link", "frame of the robot base")


class CreateBaseNode(Node):
    def __init__(self, **node_options) -> None:
        super().__init__("create_base", **node_options)
        settings = self.settings = declare_settings(self, CreateBaseSettings)
        require_positive(settings, "max_linear", "max_angular", "watchdog_timeout", "stream_timeout", "publish_rate")
        port, rate = settings.port, float(settings.publish_rate)
        self.odom_frame = settings.odom_frame
        self.base_frame = settings.base_frame
        require(bool(port), "parameter port must name a device")
        config = CreateConfig(
            port=port, baud=int(settings.baud), model=settings.model, mode=settings.mode,
            odometry=settings.odometry, max_linear=float(settings.max_linear),
            max_angular=float(settings.max_angular), watchdog_timeout=float(settings.watchdog_timeout),
            stream_timeout=float(settings.stream_timeout),
        )
        self.driver = build_driver(self, lambda on_event: CreateDriver(config, on_event=on_event))
        self.odom_publisher = self.create_publisher(Odometry, "odom", SENSOR_PUBLISHER)
        self.battery_publisher = self.create_publisher(BatteryState, "battery", SENSOR_PUBLISHER)
        self.bumper_publisher = self.create_publisher(Bool, "bumper", 10)
        self.drop_publisher = self.create_publisher(Bool, "wheel_drop", 10)
        self.create_subscription(Twist, "cmd_vel", self.on_cmd_vel, qos_profile_sensor_data)
        self.diagnostics = device_diagnostics(self, "iRobot Create", port, self.driver.health.snapshot)
        self._published_sequence = 0
        # the driver stamps sensor frames with time.monotonic(); map them onto this node's clock
        self._clock_offset = monotonic_offset(self)
        self._hazard_state: tuple[bool, bool] | None = None
        self._hazard_published_at = 0.0
        self.create_timer(1.0 / rate, self.publish_state)
        self.driver.start()

    def on_cmd_vel(self, twist: Twist) -> None:
        self.driver.drive(twist.linear.x, twist.angular.z)

    def publish_state(self) -> None:
        sequence, state = self.driver.state()
        if state is None or sequence == self._published_sequence:
            return  # nothing new: a silent robot must look silent
        self._published_sequence = sequence
        stamp = Time(seconds=state.stamp + self._clock_offset, clock_type=self.get_clock().clock_type)
        self.odom_publisher.publish(self.odometry_message(state, stamp.to_msg()))
        hazards = (state.hazards.bumped, state.hazards.wheel_dropped)
        now = stamp.nanoseconds * 1e-9
        if hazards != self._hazard_state or now - self._hazard_published_at >= 1.0:
            self._hazard_state = hazards
            self._hazard_published_at = now
            self.bumper_publisher.publish(Bool(data=hazards[0]))
            self.drop_publisher.publish(Bool(data=hazards[1]))
            self.battery_publisher.publish(self.battery_message(state, stamp.to_msg()))

    def odometry_message(self, state: CreateState, stamp) -> Odometry:
        msg = Odometry()
        msg.header.stamp = stamp
        msg.header.frame_id = self.odom_frame
        msg.child_frame_id = self.base_frame
        msg.pose.pose.position.x = state.pose.x
        msg.pose.pose.position.y = state.pose.y
        msg.pose.pose.orientation.z = math.sin(state.pose.yaw / 2.0)
        msg.pose.pose.orientation.w = math.cos(state.pose.yaw / 2.0)
        msg.twist.twist.linear.x = state.linear_velocity
        msg.twist.twist.angular.z = state.angular_velocity
        # planar odometry: x, y, yaw drift slowly; z, roll, pitch are fixed (large variance = unused)
        msg.pose.covariance = _diagonal([1e-3, 1e-3, 1e6, 1e6, 1e6, 3e-3])
        msg.twist.covariance = _diagonal([1e-3, 1e-3, 1e6, 1e6, 1e6, 3e-3])
        return msg

    def battery_message(self, state: CreateState, stamp) -> BatteryState:
        msg = BatteryState()
        msg.header.stamp = stamp
        msg.header.frame_id = self.base_frame
        msg.voltage = state.voltage
        msg.current = state.current
        msg.temperature = state.temperature
        msg.charge = state.charge
        msg.capacity = state.capacity
        msg.percentage = state.charge / state.capacity if state.capacity > 0 else math.nan
        msg.power_supply_status = (
            BatteryState.POWER_SUPPLY_STATUS_CHARGING if "charging" in state.charging_state
            and state.charging_state != "not charging" else BatteryState.POWER_SUPPLY_STATUS_DISCHARGING
        )
        msg.power_supply_technology = BatteryState.POWER_SUPPLY_TECHNOLOGY_NIMH
        msg.present = True
        return msg

    def shutdown(self) -> None:
        self.driver.stop_wheels()
        self.driver.stop()


def _diagonal(values: list[float]) -> list[float]:
    matrix = [0.0] * 36
    for i, v in enumerate(values):
        matrix[i * 7] = v
    return matrix


def main() -> int:
    return run_node(CreateBaseNode, on_shutdown=lambda node: node.shutdown())


if __name__ == "__main__":
    raise SystemExit(main())
