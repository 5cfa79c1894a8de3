"""Test helper process: join late, wait for a latched /plan (and /structure), print them as JSON.

    python -m tests.planner.plan_listener [--revision N] [--timeout S]

Waits for the first plan whose revision is at least N (default 0) and for the structure.
"""

import argparse
import json
import sys

import rclpy
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from tiling_assembly_msgs.msg import AssemblyPlan, Structure


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--revision", type=int, default=0)
    parser.add_argument("--timeout", type=float, default=30.0)
    args = parser.parse_args()
    rclpy.init()
    node = Node("plan_listener")
    latched = QoSProfile(
        depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE
    )
    plans: list[AssemblyPlan] = []
    structures: list[Structure] = []
    node.create_subscription(AssemblyPlan, "/plan", plans.append, latched)
    node.create_subscription(Structure, "/structure", structures.append, latched)
    deadline = node.get_clock().now().nanoseconds + int(args.timeout * 1e9)

    def done() -> bool:
        return bool(structures) and any(p.revision >= args.revision for p in plans)

    while not done() and node.get_clock().now().nanoseconds < deadline:
        rclpy.spin_once(node, timeout_sec=0.1)
    node.destroy_node()
    rclpy.shutdown()
    if not done():
        print(f"received {len(plans)} plans and {len(structures)} structures", file=sys.stderr)
        return 1
    plan = [p for p in plans if p.revision >= args.revision][-1]
    print(json.dumps({
        "structure": {"name": structures[0].name, "tiles": sorted(t.id for t in structures[0].tiles)},
        "plan": {
            "revision": plan.revision,
            "method": plan.method,
            "structure_name": plan.structure_name,
            "stamp_sec": plan.header.stamp.sec,
            "tasks": [
                {"robot": t.robot_name, "tiles": list(t.tile_ids), "workload": t.workload,
                 "finish": t.estimated_finish}
                for t in plan.tasks
            ],
            "supports": {str(s.tile_id): list(s.support_ids) for s in plan.supports},
            "makespan": plan.makespan,
            "lower_bound": plan.lower_bound,
        },
    }))
    return 0


if __name__ == "__main__":
    sys.exit(main())
