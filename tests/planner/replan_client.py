"""Test helper process: call /replan once and print the response as JSON.

    python -m tests.planner.replan_client --placed 1,2,3 --robots robot1 [--timeout S]
"""

import argparse
import json
import sys

import rclpy
from rclpy.node import Node

from tiling_assembly_msgs.srv import Replan


def ids(text: str) -> list[int]:
    return [int(t) for t in text.split(",") if t]


def names(text: str) -> list[str]:
    return [t for t in text.split(",") if t]


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--placed", type=ids, default=[])
    parser.add_argument("--robots", type=names, default=[])
    parser.add_argument("--timeout", type=float, default=30.0)
    args = parser.parse_args()
    rclpy.init()
    node = Node("replan_client")
    client = node.create_client(Replan, "/replan")
    if not client.wait_for_service(timeout_sec=args.timeout):
        print("the /replan service did not appear", file=sys.stderr)
        return 1
    request = Replan.Request(placed_tile_ids=args.placed, available_robots=args.robots)
    future = client.call_async(request)
    rclpy.spin_until_future_complete(node, future, timeout_sec=args.timeout)
    node.destroy_node()
    rclpy.shutdown()
    if not future.done():
        print("no answer from /replan", file=sys.stderr)
        return 1
    response = future.result()
    print(json.dumps({
        "success": response.success,
        "message": response.message,
        "revision": response.plan.revision,
        "tasks": [{"robot": t.robot_name, "tiles": list(t.tile_ids)} for t in response.plan.tasks],
        "makespan": response.plan.makespan,
        "lower_bound": response.plan.lower_bound,
    }))
    return 0


if __name__ == "__main__":
    sys.exit(main())
