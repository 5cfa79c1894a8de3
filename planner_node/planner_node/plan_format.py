"""A plan as the `plan` command prints it: the JSON object of DESIGN.md's contract, or a table
like the paper's Table 1 (each robot's tiles in placement order, with their types)."""

from __future__ import annotations

from typing import Any

from planner_node.planner import Plan
from tiling_assembly.structure import Structure

ROBOTS_PER_BLOCK = 4  # robots side by side in one block of the table


def plan_to_json(plan: Plan) -> dict[str, Any]:
    """The contract's object, plus per-robot names and times and the plan's method."""
    return {
        "robots": [
            {
                "id": k,
                "name": task.robot_name,
                "tiles": list(task.tile_ids),
                "workload": round(task.workload, 3),
                "finish": round(task.estimated_finish, 3),
                "wait": round(task.wait, 3),
            }
            for k, task in enumerate(plan.tasks, start=1)
        ],
        "supports": {str(t): list(s) for t, s in sorted(plan.supports.items())},
        "makespan": round(plan.makespan, 3),
        "lower_bound": round(plan.lower_bound, 3),
        "method": plan.method.value,
        "structure": plan.structure_name,
    }


def type_label(type_name: str) -> str:
    """'long_rectangle' -> 'Long Rectangle', as the paper's tables name tile types."""
    return " ".join(word.capitalize() for word in type_name.replace("-", "_").split("_") if word)


def plan_table(plan: Plan, structure: Structure) -> str:
    """Each robot's tiles in order with their types, robots side by side (paper, Table 1)."""
    lines = [
        f"Plan for '{plan.structure_name}' by the {plan.method.value} method, {len(plan.tasks)} robots",
        "",
    ]
    labels = {name: type_label(name) for name in structure.tile_types}  # once per type, not per tile
    for first in range(0, len(plan.tasks), ROBOTS_PER_BLOCK):
        block = list(enumerate(plan.tasks[first : first + ROBOTS_PER_BLOCK], start=first + 1))
        columns = []
        for k, task in block:
            rows = [(labels[structure.tiles[t].type_name], str(t)) for t in task.tile_ids]
            title = f"Robot {k}" if task.robot_name == f"robot{k}" else f"Robot {k} ({task.robot_name})"
            width = max([len(title)] + [len(name) for name, _ in rows])
            id_width = max([len("Tile ID")] + [len(i) for _, i in rows])
            columns.append((title, rows, width, id_width))
        lines.append("   ".join(f"{title:<{w}}  {'Tile ID':>{iw}}" for title, _, w, iw in columns))
        lines.append("   ".join("-" * w + "  " + "-" * iw for _, _, w, iw in columns))
        for row in range(max(len(rows) for _, rows, _, _ in columns)):
            cells = []
            for _, rows, w, iw in columns:
                name, tile = rows[row] if row < len(rows) else ("", "")
                cells.append(f"{name:<{w}}  {tile:>{iw}}")
            lines.append("   ".join(cells).rstrip())
        lines.append("")
    for k, task in enumerate(plan.tasks, start=1):
        lines.append(
            f"Robot {k} ({task.robot_name}): {len(task.tile_ids)} tiles, workload {task.workload:.1f} s, "
            f"waits {task.wait:.1f} s, finishes at {task.estimated_finish:.1f} s"
        )
    lines.append(
        f"Makespan {plan.makespan:.1f} s, lower bound {plan.lower_bound:.1f} s "
        f"(ratio {plan.ratio:.3f}), workload imbalance (max/mean) {plan.imbalance:.3f}"
    )
    return "\n".join(lines)
