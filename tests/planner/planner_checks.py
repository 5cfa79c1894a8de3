"""Checks shared by the planner tests, written independently of the planner's own code."""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence

import networkx as nx

from planner_node.schedule_sim import simulate_plan
from tiling_assembly.structure import Structure
from tiling_assembly.time_model import TimeModel


def plan_problems(
    structure: Structure, orders: Mapping[str, Sequence[int]], time_model: TimeModel
) -> list[str]:
    """Everything wrong with a plan: tiles missing or repeated, orders against precedence, deadlock."""
    problems = []
    placed = [t for order in orders.values() for t in order]
    if sorted(placed) != sorted(structure.tiles):
        missing = sorted(set(structure.tiles) - set(placed))
        extra = sorted(t for t in set(placed) if placed.count(t) > 1 or t not in structure.tiles)
        problems.append(f"tiles missing {missing[:5]} or repeated/unknown {extra[:5]}")
        return problems
    for robot, order in orders.items():
        position = {t: k for k, t in enumerate(order)}
        for t in order:
            for s in structure.supports[t]:
                if s in position and position[s] > position[t]:
                    problems.append(f"{robot} places {t} before its support {s}")
    schedule = simulate_plan(structure, time_model, orders)
    if not schedule.completed:
        problems.append(f"the team deadlocks at tiles {list(schedule.blocked_tiles)}")
    else:
        for robot in schedule.robots:
            for timing in robot.tiles:
                for s in structure.supports[timing.tile_id]:
                    if schedule.timing(s).place_end > timing.place_start + 1e-9:
                        problems.append(f"tile {timing.tile_id} placed before its support {s}")
    return problems


def region_is_connected(structure: Structure, tiles: Iterable[int]) -> bool:
    """True when `tiles` form one connected piece of the contact graph within each structure piece."""
    graph = nx.Graph()
    graph.add_nodes_from(structure.tiles)
    graph.add_edges_from(structure.contacts)
    graph.add_edges_from((s, t) for t, below in structure.supports.items() for s in below)
    chosen = set(tiles)
    for piece in nx.connected_components(graph):
        inside = chosen & piece
        if inside and not nx.is_connected(graph.subgraph(inside)):
            return False
    return True
