"""Makespan improvement by local search over trades and orders (beyond paper section 2.1).

The paper balances workloads and minimises waiting, but a balanced plan can still finish late: a
robot that waits for its neighbours finishes after its workload. This step takes the traded
partition and searches, with the team simulation (`schedule_sim`) as the objective:

1. order every robot's tiles with both sequencing policies (the paper's maximum slack and the
   critical-path list schedule) and keep the orders that finish first;
2. repeatedly move one border tile from the robot that finishes last to a touching robot that
   finishes earlier (regions stay connected and non-empty, as in node trading), re-sequence with
   the critical-path policy and keep the move only when the makespan falls (or stays and the total
   waiting falls); stop when no move of the last robot helps or the time budget is spent.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from planner_node.assembly_graph import AssemblyGraph
from planner_node.node_trading import RegionBorders
from planner_node.schedule_sim import SimulationResult, simulate_orders
from planner_node.sequencing import Policy, Sequencing, sequence_tiles

IntArray = NDArray[np.int64]
FloatArray = NDArray[np.float64]

CANDIDATES_PER_NEIGHBOUR = 4  # border tiles tried per neighbouring robot and round
IMPROVEMENT_EPSILON = 1e-6  # s
LOCAL_SEARCH = False


@dataclass(frozen=True, eq=False)
class ImprovedPlan:
    owner: IntArray
    orders: list[list[int]]
    result: SimulationResult
    policy: str
    moves: int
    helped: int
    evaluations: int
    start: str


def _score(result: SimulationResult) -> tuple[float, float]:
    return (result.makespan, result.total_wait)


def _better(a: SimulationResult, b: SimulationResult) -> bool:
    ma, wa = _score(a)
    mb, wb = _score(b)
    return ma < mb - IMPROVEMENT_EPSILON or (ma <= mb + IMPROVEMENT_EPSILON and wa < wb - IMPROVEMENT_EPSILON)


def best_sequencing(
    graph: AssemblyGraph, owner: IntArray, n_robots: int, distance: FloatArray
) -> tuple[Sequencing, SimulationResult, str]:
    """Orders by every policy, simulated; the ones that finish first (then wait least)."""
    best = None
    for name, policy, helping in (
        ("critical-path", Policy.CRITICAL_PATH, False),
        ("max-slack", Policy.MAX_SLACK, False),
        ("critical-path+help", Policy.CRITICAL_PATH, True),
    ):
        sequencing = sequence_tiles(graph, owner, n_robots, policy, distance, helping)
        result = simulate_orders(graph, sequencing.orders)
        if best is None or _better(result, best[1]):
            best = (sequencing, result, name)
    assert best is not None
    return best


def improve_plan(
    graph: AssemblyGraph,
    partitions: Mapping[str, IntArray],
    n_robots: int,
    distance: FloatArray,
    time_limit: float,
) -> ImprovedPlan:
    """Local search from the best of the traded `partitions` (see the module docstring)."""
    deadline = time.perf_counter() + time_limit
    best = None
    for name, candidate in partitions.items():
        sequencing, result, policy = best_sequencing(graph, candidate, n_robots, distance)
        if best is None or _better(result, best[1]):
            best = (sequencing, result, policy, name, candidate)
    assert best is not None
    sequencing, result, policy, start, owner = best
    evaluations = 3 * len(partitions)
    moves = 0
    regions = RegionBorders(graph, owner, n_robots)
    cost = regions.cost
    improved = LOCAL_SEARCH
    while improved and time.perf_counter() < deadline:
        improved = False
        finish = result.robot_finish
        late = int(np.argmax(finish))
        targets = sorted(regions.neighbor_regions(late), key=lambda r: finish[r])
        for taker in targets:
            room = finish[late] - finish[taker]
            if room <= IMPROVEMENT_EPSILON:
                break
            border = [t for t in regions.border.get((late, taker), ()) if cost[t] < room]
            border.sort(key=lambda t: (-regions.counts[t][taker], abs(cost[t] - 0.5 * room), t))
            tried = 0
            for tile in border:
                if tried >= CANDIDATES_PER_NEIGHBOUR or time.perf_counter() >= deadline:
                    break
                if not regions.can_leave(tile):
                    continue
                tried += 1
                regions.move(tile, taker)
                trial_owner = np.array(regions.owner, dtype=np.int64)
                trial_seq = sequence_tiles(graph, trial_owner, n_robots, Policy.CRITICAL_PATH, distance)
                trial = simulate_orders(graph, trial_seq.orders)
                evaluations += 1
                if _better(trial, result):
                    sequencing, result, policy = trial_seq, trial, "critical-path"
                    moves += 1
                    improved = True
                    break
                regions.move(tile, late)
            if improved:
                break
    return ImprovedPlan(
        owner=sequencing.owner,
        orders=sequencing.orders,
        result=result,
        policy=policy,
        moves=moves,
        helped=sequencing.helped,
        evaluations=evaluations,
        start=start,
    )
