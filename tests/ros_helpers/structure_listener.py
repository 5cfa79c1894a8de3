"""Test helper process: join late, receive the latched structure, print it as JSON, exit."""

import json
import sys

import rclpy
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from tiling_assembly.messages import structure_from_msg
from tiling_assembly_msgs.msg import Structure


def main() -> int:
    timeout = float(sys.argv[1]) if len(sys.argv) > 1 else 20.0
    rclpy.init()
    node = Node("structure_listener")
    latched = QoSProfile(
        depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE
    )
    received: list[Structure] = []
    node.create_subscription(Structure, "structure", received.append, latched)
    deadline = node.get_clock().now().nanoseconds + int(timeout * 1e9)
    while not received and node.get_clock().now().nanoseconds < deadline:
        rclpy.spin_once(node, timeout_sec=0.1)
    node.destroy_node()
    rclpy.shutdown()
    if not received:
        print("no structure received", file=sys.stderr)
        return 1
    structure = structure_from_msg(received[0])
    print(json.dumps({
        "name": structure.name,
        "stamp_sec": received[0].header.stamp.sec,
        "tiles": structure.tile_ids,
        "supports": {str(k): list(v) for k, v in structure.supports.items()},
    }))
    return 0


if __name__ == "__main__":
    sys.exit(main())
