"""`crustcrawler_arm`: the CrustCrawler 5-DOF arm and gripper of an M3 robot (paper section 3.1).

    ros2 run hardware_drivers crustcrawler_arm --ros-args -r __ns:=/robot1 -p port:=/dev/ttyUSB1 \\
        --params-file config/crustcrawler_arm.yaml

Publishes ``joint_states`` (sensor_msgs/JointState at ``rate``: position rad, velocity rad/s,
effort N·m estimated from the servo's load) and ``/diagnostics`` (joint errors: overload,
overheating, input voltage..., joints not answering). Accepts

* ``joint_trajectory`` (trajectory_msgs/JointTrajectory): points run one after the other, each
  reached at its ``time_from_start`` when the joints' speed limits allow (slower otherwise: the
  next point waits until the arm is within ``goal_tolerance`` of this one, at most
  ``trajectory_wait`` beyond its time);
  a trajectory with a point outside the joint limits is refused as a whole (one log line);
* ``named_pose`` (std_msgs/String): a pose of ``named_pose_names`` (``config/crustcrawler_arm.yaml``),
  or ``gripper_open`` / ``gripper_closed``;
* service ``torque_enable`` (std_srvs/SetBool): torque on (re-arming servos an alarm shut down)
  or off.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_msgs.msg import String
from std_srvs.srv import SetBool
from trajectory_msgs.msg import JointTrajectory

from hardware_drivers.dynamixel_driver import ArmConfig, ArmDriver, JointGoalError, joint_configs
from hardware_drivers.node_support import (
    EventSink,
    build_driver,
    declare_numbers,
    device_diagnostics,
    numbers,
    require,
    require_positive,
    run_node,
)
from tiling_ros.parameters import declare_settings, declare_values, setting, setting_names
from tiling_ros.qos import SENSOR_PUBLISHER
from tiling_ros.stamps import stamp_to_seconds

_BUS = ArmConfig(port="", joints=())  # the bus defaults

ARM_JOINT_NAMES = ["base_yaw", "shoulder", "elbow", "wrist_pitch", "wrist_roll"]
JOINT_NAMES = [*ARM_JOINT_NAMES, "gripper"]
# per joint, when the arm description does not list it
LOWER_LIMIT, UPPER_LIMIT, MAX_VELOCITY = -2.6, 2.6, 1.0  # rad, rad, rad/s
POSE_ANGLE, OFFSET, DIRECTION = 0.0, 0.0, 1  # rad, rad, +1 or -1


@dataclass(frozen=True)
class ArmDescriptionSettings:
    """The arm's description (config/crustcrawler_arm.yaml), shared by crustcrawler_arm and m3_robot.

    The per-joint lists default to one value per joint of `joint_names` (`for_joints`); each named
    pose is a parameter of its own, `named_poses.<name>`, of one angle per arm joint.
    """

    joint_names: list[str] = setting(JOINT_NAMES, "joint names: the five arm joints, then the gripper")  # noqa: RUF009
    joint_lower_limits: list[float] = setting(  # noqa: RUF009 - a field() with a default_factory
        [LOWER_LIMIT] * len(JOINT_NAMES), "rad, lower joint limits")
    joint_upper_limits: list[float] = setting(  # noqa: RUF009 - a field() with a default_factory
        [UPPER_LIMIT] * len(JOINT_NAMES), "rad, upper joint limits")
    joint_max_velocities: list[float] = setting(  # noqa: RUF009 - a field() with a default_factory
        [MAX_VELOCITY] * len(JOINT_NAMES), "rad/s, joint speed limits")
    gripper_joint: str = setting("gripper", "name of the gripper joint")
    gripper_open: float = setting(0.6, "rad, gripper joint angle fully open")
    gripper_closed: float = setting(-0.6, "rad, gripper joint angle fully closed")
    named_pose_names: list[str] = setting(["home", "stow"], "names of the named arm poses")  # noqa: RUF009
    arm_link_lengths: list[float] = setting(  # noqa: RUF009 - a field() with a default_factory
        [0.065, 0.152, 0.132, 0.105],
        "m: shoulder height above the arm base, upper arm, forearm, wrist axis to fingertips")

    @classmethod
    def for_joints(cls, names: list[str]) -> ArmDescriptionSettings:
        """The defaults for an arm of these joints."""
        n = len(names)
        return cls(joint_names=list(names), joint_lower_limits=[LOWER_LIMIT] * n,
                   joint_upper_limits=[UPPER_LIMIT] * n, joint_max_velocities=[MAX_VELOCITY] * n)


@dataclass(frozen=True)
class CrustCrawlerArmSettings:
    """The parameters of crustcrawler_arm besides the arm's description (config/hardware_drivers.yaml
    and config/crustcrawler_arm.yaml), with their defaults; the per-joint lists as `for_joints`."""

    port: str = setting("/dev/ttyUSB1", "serial device of the Dynamixel bus (a pty path works)")
    baud: int = setting(_BUS.baud, "baud rate of the bus (AX-12 default 1000000)")
    servo_ids: list[int] = setting(  # noqa: RUF009 - a field() with a default_factory
        list(range(1, len(JOINT_NAMES) + 1)), "servo id of each joint")
    joint_offsets: list[float] = setting(  # noqa: RUF009 - a field() with a default_factory
        [OFFSET] * len(JOINT_NAMES), "rad, servo angle when the joint is at 0")
    joint_directions: list[int] = setting(  # noqa: RUF009 - a field() with a default_factory
        [DIRECTION] * len(JOINT_NAMES), "+1 or -1: servo angle = direction * joint angle + offset")
    rate: float = setting(_BUS.rate, "Hz, joint state reads and goal writes")
    reply_timeout: float = setting(_BUS.reply_timeout, "s to wait for a servo's status packet")
    retries: int = setting(_BUS.retries, "attempts per servo transaction before giving up")
    stall_torque: float = setting(1.5, "N·m, AX-12 stall torque (effort estimate)")
    goal_tolerance: float = setting(_BUS.goal_tolerance, "rad, a trajectory point counts as reached this close")
    trajectory_wait: float = setting(
        _BUS.trajectory_wait, "s a lagging trajectory point is waited for before the next is sent")

    @classmethod
    def for_joints(cls, count: int) -> CrustCrawlerArmSettings:
        """The defaults for an arm of `count` joints."""
        return cls(servo_ids=list(range(1, count + 1)), joint_offsets=[OFFSET] * count,
                   joint_directions=[DIRECTION] * count)


def declare_arm_description(node: Node) -> dict:
    """The arm's description (``config/crustcrawler_arm.yaml``), shared with ``m3_robot``."""
    names = list(declare_values(node, ArmDescriptionSettings(), names=["joint_names"])["joint_names"])
    n = len(names)
    require(n >= 1, "parameter joint_names is empty")
    defaults = ArmDescriptionSettings.for_joints(names)  # the per-joint lists sized to these joints
    rest = [name for name in setting_names(ArmDescriptionSettings) if name != "joint_names"]
    arm = replace(defaults, **declare_values(node, defaults, names=rest))
    lower = numbers(arm, "joint_lower_limits", n)
    upper = numbers(arm, "joint_upper_limits", n)
    velocities = numbers(arm, "joint_max_velocities", n)
    gripper = arm.gripper_joint
    require(gripper in names, f"gripper_joint '{gripper}' is not in joint_names")
    gripper_open, gripper_closed = float(arm.gripper_open), float(arm.gripper_closed)
    arm_joints = [j for j in names if j != gripper]
    poses = {}
    for pose in list(arm.named_pose_names):
        values = declare_numbers(node, f"named_poses.{pose}", [POSE_ANGLE] * len(arm_joints),
                                 f"rad, arm joint angles of the pose '{pose}' ({', '.join(arm_joints)})",
                                 len(arm_joints))
        poses[pose] = dict(zip(arm_joints, values, strict=True))
    links = numbers(arm, "arm_link_lengths", 4)
    require(all(v > 0 for v in links), "arm_link_lengths must be positive")
    limits = dict(zip(names, zip(lower, upper, strict=True), strict=True))
    for pose, values in poses.items():
        for joint, angle in values.items():
            lo, hi = limits[joint]
            require(lo <= angle <= hi, f"named pose '{pose}': {joint} {angle} rad outside [{lo}, {hi}]")
    for label, angle in (("gripper_open", gripper_open), ("gripper_closed", gripper_closed)):
        lo, hi = limits[gripper]
        require(lo <= angle <= hi, f"{label} {angle} rad outside the gripper's limits [{lo}, {hi}]")
    return {
        "names": names, "lower": lower, "upper": upper, "velocities": velocities, "gripper": gripper,
        "gripper_open": gripper_open, "gripper_closed": gripper_closed, "poses": poses,
        "arm_joints": arm_joints, "links": links,
    }


class CrustCrawlerArmNode(Node):
    def __init__(self, **node_options) -> None:
        super().__init__("crustcrawler_arm", **node_options)
        arm = declare_arm_description(self)
        n = len(arm["names"])
        settings = self.settings = declare_settings(
            self, CrustCrawlerArmSettings, defaults=CrustCrawlerArmSettings.for_joints(n)
        )
        port, baud = settings.port, int(settings.baud)
        ids = [int(v) for v in settings.servo_ids]
        offsets = numbers(settings, "joint_offsets", n)
        directions = [int(v) for v in settings.joint_directions]
        require_positive(settings, "rate", "reply_timeout")
        rate, reply_timeout = float(settings.rate), float(settings.reply_timeout)
        retries = int(settings.retries)
        require_positive(settings, "stall_torque", "goal_tolerance", "trajectory_wait")
        self.stall_torque = float(settings.stall_torque)
        require(bool(port), "parameter port must name a device")

        def arm_driver(on_event: EventSink) -> ArmDriver:
            joints = joint_configs(arm["names"], ids, offsets, directions, arm["lower"], arm["upper"],
                                   arm["velocities"])
            config = ArmConfig(port=port, joints=joints, baud=baud, rate=rate, reply_timeout=reply_timeout,
                               retries=retries, goal_tolerance=float(settings.goal_tolerance),
                               trajectory_wait=float(settings.trajectory_wait))
            return ArmDriver(config, on_event=on_event)

        self.driver = build_driver(self, arm_driver)
        self.arm = arm
        self.joint_publisher = self.create_publisher(JointState, "joint_states", SENSOR_PUBLISHER)
        self.create_subscription(JointTrajectory, "joint_trajectory", self.on_trajectory, 10)
        self.create_subscription(String, "named_pose", self.on_named_pose, 10)
        self.create_service(SetBool, "torque_enable", self.on_torque)
        self.diagnostics = device_diagnostics(self, "CrustCrawler arm", port, self.driver.health.snapshot)
        self._trajectory: list[tuple[float, dict[str, float]]] = []  # (time from start, goals)
        self._trajectory_start = 0.0
        self._point_time = 0.0
        self._point_goals: dict[str, float] = {}  # the point sent last
        self._published_sequence = 0
        self.create_timer(1.0 / rate, self.publish_joint_states)
        self.create_timer(0.02, self.advance_trajectory)
        self.driver.start()

    # ------------------------------------------------------------------ commands
    def on_trajectory(self, msg: JointTrajectory) -> None:
        if not msg.points:
            self._trajectory = []
            return
        points = []
        try:
            for point in msg.points:
                if len(point.positions) != len(msg.joint_names):
                    raise JointGoalError(f"a point has {len(point.positions)} positions for "
                                         f"{len(msg.joint_names)} joints")
                goals = dict(zip(msg.joint_names, point.positions, strict=True))
                self.driver.check_goal(goals)
                t = stamp_to_seconds(point.time_from_start)
                points.append((t, goals))
        except JointGoalError as error:
            self.get_logger().error(f"trajectory refused: {error}")
            self.driver.health.count("goals_refused")
            return
        self._trajectory = points
        self._trajectory_start = self._now()
        self._point_time = 0.0
        self._point_goals = {}
        self.advance_trajectory()

    def advance_trajectory(self) -> None:
        if not self._trajectory:
            return
        late = self._now() - self._trajectory_start - self._point_time
        if late + 1e-3 < 0:
            return  # the point sent last is due later
        # an arm that lags behind (speed limits, a busy bus) finishes the point first: sending the
        # next one at once would cut the corner and skip it; a joint held up for good (the gripper
        # on an object) lets the trajectory go on after trajectory_wait
        if not self._point_reached() and late < self.driver.config.trajectory_wait:
            return
        t, goals = self._trajectory.pop(0)
        self.driver.set_goals(goals, duration=max(t - self._point_time, 0.05))
        self._point_time = t
        self._point_goals = goals

    def _point_reached(self) -> bool:
        readings = self.driver.readings()[1]
        tolerance = self.driver.config.goal_tolerance
        return all(name in readings and abs(readings[name].position - angle) <= tolerance
                   for name, angle in self._point_goals.items())

    def on_named_pose(self, msg: String) -> None:
        name = msg.data.strip()
        if name == "gripper_open":
            goals = {self.arm["gripper"]: self.arm["gripper_open"]}
        elif name == "gripper_closed":
            goals = {self.arm["gripper"]: self.arm["gripper_closed"]}
        elif name in self.arm["poses"]:
            goals = self.arm["poses"][name]
        else:
            known = ", ".join([*self.arm["poses"], "gripper_open", "gripper_closed"])
            self.get_logger().error(f"unknown named pose '{name}' (known: {known})")
            return
        self._trajectory = []
        self.driver.set_goals(goals)
        self.get_logger().info(f"moving to named pose '{name}'")

    def on_torque(self, request: SetBool.Request, response: SetBool.Response) -> SetBool.Response:
        response.success, response.message = self.driver.set_torque(request.data)
        return response

    # ------------------------------------------------------------------ state
    def publish_joint_states(self) -> None:
        sequence, readings = self.driver.readings()
        if not readings or sequence == self._published_sequence:
            return
        self._published_sequence = sequence
        msg = JointState()
        msg.header.stamp = self.get_clock().now().to_msg()
        ordered = [readings[n] for n in self.arm["names"] if n in readings]
        msg.name = [r.name for r in ordered]
        msg.position = [r.position for r in ordered]
        msg.velocity = [r.velocity for r in ordered]
        msg.effort = [r.load * self.stall_torque for r in ordered]
        self.joint_publisher.publish(msg)

    def _now(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def shutdown(self) -> None:
        self.driver.stop()


def main() -> int:
    return run_node(CrustCrawlerArmNode, on_shutdown=lambda node: node.shutdown())


if __name__ == "__main__":
    raise SystemExit(main())

