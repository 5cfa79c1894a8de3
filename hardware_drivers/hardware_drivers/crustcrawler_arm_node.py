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

from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_msgs.msg import String
from std_srvs.srv import SetBool
from trajectory_msgs.msg import JointTrajectory

from hardware_drivers.dynamixel_driver import ArmConfig, ArmDriver, JointGoalError, joint_configs
from hardware_drivers.node_support import (
    SENSOR_PUBLISHER_QOS,
    DiagnosticsReporter,
    ParameterError,
    declare,
    floats,
    log_event,
    positive,
    require,
    run_node,
)

ARM_JOINT_NAMES = ["base_yaw", "shoulder", "elbow", "wrist_pitch", "wrist_roll"]


def declare_arm_description(node: Node) -> dict:
    """The arm's description (``config/crustcrawler_arm.yaml``), shared with ``m3_robot``."""
    names = list(declare(node, "joint_names", [*ARM_JOINT_NAMES, "gripper"],
                         "joint names: the five arm joints, then the gripper"))
    n = len(names)
    require(n >= 1, "parameter joint_names is empty")
    lower = floats(node, "joint_lower_limits", [-2.6] * n, "rad, lower joint limits", n)
    upper = floats(node, "joint_upper_limits", [2.6] * n, "rad, upper joint limits", n)
    velocities = floats(node, "joint_max_velocities", [1.0] * n, "rad/s, joint speed limits", n)
    gripper = declare(node, "gripper_joint", "gripper", "name of the gripper joint")
    require(gripper in names, f"gripper_joint '{gripper}' is not in joint_names")
    gripper_open = float(declare(node, "gripper_open", 0.6, "rad, gripper joint angle fully open"))
    gripper_closed = float(declare(node, "gripper_closed", -0.6, "rad, gripper joint angle fully closed"))
    pose_names = list(declare(node, "named_pose_names", ["home", "stow"], "names of the named arm poses"))
    arm_joints = [j for j in names if j != gripper]
    poses = {}
    for pose in pose_names:
        values = floats(node, f"named_poses.{pose}", [0.0] * len(arm_joints),
                        f"rad, arm joint angles of the pose '{pose}' ({', '.join(arm_joints)})",
                        len(arm_joints))
        poses[pose] = dict(zip(arm_joints, values, strict=True))
    links = floats(node, "arm_link_lengths", [0.065, 0.152, 0.132, 0.105],
                   "m: shoulder height above the arm base, upper arm, forearm, wrist axis to fingertips", 4)
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
        port = declare(self, "port", "/dev/ttyUSB1", "serial device of the Dynamixel bus (a pty path works)")
        baud = int(declare(self, "baud", 1000000, "baud rate of the bus (AX-12 default 1000000)"))
        arm = declare_arm_description(self)
        n = len(arm["names"])
        ids = [int(v) for v in declare(self, "servo_ids", list(range(1, n + 1)), "servo id of each joint")]
        offsets = floats(self, "joint_offsets", [0.0] * n, "rad, servo angle when the joint is at 0", n)
        directions = [int(v) for v in declare(self, "joint_directions", [1] * n,
                                              "+1 or -1: servo angle = direction * joint angle + offset")]
        rate = positive(self, "rate", 20.0, "Hz, joint state reads and goal writes")
        reply_timeout = positive(self, "reply_timeout", 0.03, "s to wait for a servo's status packet")
        retries = int(declare(self, "retries", 3, "attempts per servo transaction before giving up"))
        self.stall_torque = positive(self, "stall_torque", 1.5, "N·m, AX-12 stall torque (effort estimate)")
        require(bool(port), "parameter port must name a device")
        try:
            joints = joint_configs(arm["names"], ids, offsets, directions, arm["lower"], arm["upper"],
                                   arm["velocities"])
            config = ArmConfig(port=port, joints=joints, baud=baud, rate=rate, reply_timeout=reply_timeout,
                               retries=retries)
            self.driver = ArmDriver(config, on_event=lambda level, text: log_event(self, level, text))
        except ValueError as error:
            raise ParameterError(str(error)) from None
        self.arm = arm
        self.joint_publisher = self.create_publisher(JointState, "joint_states", SENSOR_PUBLISHER_QOS)
        self.create_subscription(JointTrajectory, "joint_trajectory", self.on_trajectory, 10)
        self.create_subscription(String, "named_pose", self.on_named_pose, 10)
        self.create_service(SetBool, "torque_enable", self.on_torque)
        self.diagnostics = DiagnosticsReporter(
            self, f"{self.get_fully_qualified_name()}: CrustCrawler arm", port, self.driver.health.snapshot
        )
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
                t = point.time_from_start.sec + point.time_from_start.nanosec * 1e-9
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

