"""The experiment's observer starts a trial's clock only once the VI robot can see (real ROS graph)."""

from __future__ import annotations

import time

from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from ros_helpers.isolated_domains import fresh_domain
from sensor_msgs.msg import PointCloud2

from tiling_sim.experiment_observer import ExperimentObserver
from tiling_sim.trial_record import TrialRecord

CAMERA, VI_NODE = "/vi/camera/depth/points", "/vi/vi_node"


def _settles_to(observer: ExperimentObserver, expected: list[str], timeout: float = 10.0) -> list[str]:
    deadline = time.monotonic() + timeout
    while (waiting := observer.unread_sensors([(CAMERA, VI_NODE)])) != expected and time.monotonic() < deadline:
        time.sleep(0.05)
    return waiting


def test_the_clock_waits_until_vi_node_reads_its_camera_as_the_camera_offers_it() -> None:
    """On a loaded host the clock once ran 4.5 s of wall time before vi_node had subscribed:
    its first scan was lost and the VI robot's path, with every detection after it, differed from a
    run on a quiet host."""
    context = fresh_domain().context
    observer = ExperimentObserver(TrialRecord(trial=1, seed=1, removals_planned=0), ["robot1"], context=context)
    camera = Node("sim_vi", namespace="vi", context=context)
    vi_node = Node("vi_node", namespace="vi", context=context)
    try:
        assert observer.unread_sensors([(CAMERA, VI_NODE)]) == [f"{VI_NODE} reading {CAMERA}"]
        camera.create_publisher(PointCloud2, CAMERA, QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE))
        best_effort = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)
        vi_node.create_subscription(PointCloud2, CAMERA, lambda _: None, best_effort)
        # Fast DDS drops a fragmented cloud on a best-effort reader: not seeing yet
        assert _settles_to(observer, [f"{VI_NODE} reading {CAMERA} reliably, as it is offered"]) == [
            f"{VI_NODE} reading {CAMERA} reliably, as it is offered"]
        vi_node.create_subscription(PointCloud2, CAMERA, lambda _: None,
                                    QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE))
        assert _settles_to(observer, []) == []
    finally:
        for node in (observer, camera, vi_node):
            node.destroy_node()
