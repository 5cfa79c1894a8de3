"""Conversion of a plan to `tiling_assembly_msgs/AssemblyPlan` (the node's only message code)."""

from __future__ import annotations

from planner_node.planner import Plan
from tiling_assembly_msgs.msg import AssemblyPlan, AssemblyTask, SupportRelation


def plan_to_msg(plan: Plan, revision: int, frame_id: str = "map") -> AssemblyPlan:
    """The message for a plan (header.stamp left for the publisher to set)."""
    msg = AssemblyPlan()
    msg.header.frame_id = frame_id
    msg.revision = revision
    msg.structure_name = plan.structure_name
    msg.method = plan.method.value
    msg.tasks = [
        AssemblyTask(
            robot_name=task.robot_name,
            tile_ids=[int(t) for t in task.tile_ids],
            workload=float(task.workload),
            estimated_finish=float(task.estimated_finish),
        )
        for task in plan.tasks
    ]
    msg.supports = [
        SupportRelation(tile_id=int(t), support_ids=[int(s) for s in below])
        for t, below in sorted(plan.supports.items())
    ]
    msg.makespan = float(plan.makespan)
    msg.lower_bound = float(plan.lower_bound)
    return msg
