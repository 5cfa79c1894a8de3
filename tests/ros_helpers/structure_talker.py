"""Test helper process: publish a structure file once, latched (transient_local), then stay up."""

import sys

from rclpy.node import Node

from tiling_assembly.messages import structure_to_msg
from tiling_assembly.structure_file import load_structure
from tiling_assembly_msgs.msg import Structure
from tiling_ros.qos import LATCHED
from tiling_ros.spinning import run_node


def talker(path: str) -> Node:
    """A node that has published the structure of `path` once, latched."""
    structure = load_structure(path)
    node = Node("structure_talker")
    publisher = node.create_publisher(Structure, "structure", LATCHED)
    msg = structure_to_msg(structure)
    msg.header.stamp = node.get_clock().now().to_msg()
    publisher.publish(msg)
    print("published", flush=True)
    return node


def main() -> int:
    return run_node(lambda: talker(sys.argv[1]))


if __name__ == "__main__":
    sys.exit(main())
