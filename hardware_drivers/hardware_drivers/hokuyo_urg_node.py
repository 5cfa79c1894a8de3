"""`hokuyo_urg`: the Hokuyo URG laser of an M3 robot (paper section 3.1: it finds the tiles).

    ros2 run hardware_drivers hokuyo_urg --ros-args -r __ns:=/robot1 -p port:=/dev/ttyACM0

Publishes ``scan`` (sensor_msgs/LaserScan, reliable as REP 2003 asks of drivers; angles from the
sensor's AMIN/AMAX/AFRT/ARES; NaN where the sensor reported an error code, +inf beyond DMAX) and
``/diagnostics`` (model, firmware, scans, corrupt and faulty scans dropped, reconnects). The
sensor is switched from SCIP 1.1 to 2.0 when needed and reconnected after errors (see
``urg_driver``).
"""

from __future__ import annotations

from dataclasses import dataclass

from rclpy.node import Node
from rclpy.time import Time
from sensor_msgs.msg import LaserScan

from hardware_drivers.node_support import (
    build_driver,
    device_diagnostics,
    monotonic_offset,
    require,
    require_positive,
    run_node,
)
from hardware_drivers.urg_driver import UrgConfig, UrgDriver
from tiling_ros.parameters import declare_settings, setting
from tiling_ros.qos import SENSOR_PUBLISHER

_URG = UrgConfig(port="/dev/ttyACM0")


@dataclass(frozen=True)
class HokuyoUrgSettings:
    """The parameters of hokuyo_urg (config/hardware_drivers.yaml), with their defaults."""

    port: str = setting(_URG.port, "serial device of the URG (a pty path works)")
    baud: int = setting(_URG.baud, "baud rate tried first (then 19200, 38400, 115200)")
    frame_id: str = setting("laser", "frame of the scans")
    cluster: int = setting(_URG.cluster, "adjacent steps merged into one range (1..99)")
    skip: int = setting(_URG.skip, "scans skipped between two published (0..9)")
    error_limit: int = setting(_URG.error_limit, "bad scans in a row before reconnecting")
    scan_timeout: float = setting(_URG.scan_timeout, "s without a scan before reconnecting")


class HokuyoUrgNode(Node):
    def __init__(self, **node_options) -> None:
        super().__init__("hokuyo_urg", **node_options)
        settings = self.settings = declare_settings(self, HokuyoUrgSettings)
        require_positive(settings, "scan_timeout")
        port = settings.port
        self.frame_id = settings.frame_id
        require(bool(port), "parameter port must name a device")
        self.driver = build_driver(self, lambda on_event: UrgDriver(
            UrgConfig(port=port, baud=int(settings.baud), cluster=int(settings.cluster), skip=int(settings.skip),
                      error_limit=int(settings.error_limit), scan_timeout=float(settings.scan_timeout)),
            on_event=on_event,
        ))
        self.scan_publisher = self.create_publisher(LaserScan, "scan", SENSOR_PUBLISHER)
        self.diagnostics = device_diagnostics(self, "Hokuyo URG", port, self.driver.health.snapshot)
        self._published_sequence = 0
        # map the driver's monotonic stamps onto this node's clock
        self._clock_offset = monotonic_offset(self)
        self.create_timer(0.01, self.publish_scan)
        self.driver.start()

    def publish_scan(self) -> None:
        sequence, scan = self.driver.latest_scan()
        if scan is None or sequence == self._published_sequence:
            return
        self._published_sequence = sequence
        msg = LaserScan()
        msg.header.stamp = Time(seconds=scan.stamp + self._clock_offset).to_msg()
        msg.header.frame_id = self.frame_id
        msg.angle_min = scan.angle_min
        msg.angle_max = scan.angle_max
        msg.angle_increment = scan.angle_increment
        msg.time_increment = scan.time_increment
        msg.scan_time = scan.scan_time
        msg.range_min = scan.range_min
        msg.range_max = scan.range_max
        msg.ranges = scan.ranges.astype(float).tolist()
        self.scan_publisher.publish(msg)

    def shutdown(self) -> None:
        self.driver.stop()


def main() -> int:
    return run_node(HokuyoUrgNode, on_shutdown=lambda node: node.shutdown())


if __name__ == "__main__":
    raise SystemExit(main())
