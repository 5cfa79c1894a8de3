"""A ROS 2 talker or listener for the virtual-hosts tests (run on a host with `VirtualHosts.command`).

    virtual_hosts_peer.py talk PERIOD   publish "N" on vh_chatter (std_msgs/String) and N on vh_plain
                                        (std_msgs/Int64: a plain bounded type, the kind Fast DDS could
                                        hand over by data-sharing) every PERIOD seconds
    virtual_hosts_peer.py listen        print "TOPIC N SECONDS" per message received (monotonic time)

Exits 0 at SIGINT or SIGTERM.
"""

from __future__ import annotations

import sys
import time

from rclpy.node import Node
from std_msgs.msg import Int64, String

from tiling_ros.spinning import run_node


class Talker(Node):
    def __init__(self, period: float) -> None:
        super().__init__("vh_talker")
        self.text = self.create_publisher(String, "vh_chatter", 10)
        self.plain = self.create_publisher(Int64, "vh_plain", 10)
        self.count = 0
        self.create_timer(period, self.publish)

    def publish(self) -> None:
        self.count += 1
        self.text.publish(String(data=str(self.count)))
        self.plain.publish(Int64(data=self.count))


class Listener(Node):
    def __init__(self) -> None:
        super().__init__("vh_listener")
        self.create_subscription(String, "vh_chatter", lambda m: self.show("chatter", m.data), 10)
        self.create_subscription(Int64, "vh_plain", lambda m: self.show("plain", m.data), 10)
        print("listening", flush=True)

    def show(self, topic: str, data: object) -> None:
        print(f"{topic} {data} {time.monotonic():.3f}", flush=True)


if __name__ == "__main__":
    if sys.argv[1] == "talk":
        sys.exit(run_node(lambda: Talker(float(sys.argv[2]))))
    sys.exit(run_node(Listener))
