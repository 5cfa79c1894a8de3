"""Test helper process: publish a structure file once, latched (transient_local), then stay up."""

import sys

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from tiling_assembly.messages import structure_to_msg
from tiling_assembly.structure_file import load_structure
from tiling_assembly_msgs.msg import Structure


def main() -> None:
    structure = load_structure(sys.argv[1])
    rclpy.init()
    node = Node("structure_talker")
    latched = QoSProfile(
        depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE
    )
    publisher = node.create_publisher(Structure, "structure", latched)
    msg = structure_to_msg(structure)
    msg.header.stamp = node.get_clock().now().to_msg()
    publisher.publish(msg)
    print("published", flush=True)
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    main()
