"""Makespan improvement: pick the best start, then local search over trades and orders (beyond
paper section 2.1).

The paper balances workloads and minimises waiting, but a balanced plan can still finish late: a
robot that waits for its neighbours finishes after its workload. This step uses the team
simulation (`schedule_sim`) as the objective (makespan, then total waiting):

1. every candidate partition (the paper's traded Dijkstra regions, the layer-balanced ones of
   `layer_partition`) is sequenced with every policy of `sequencing` (the paper's maximum slack,
   critical-path list scheduling, and the same with robots helping others when the helped robot
   would finish later, or whenever the helper would wait); the plan that finishes first is the
   start, the most local one among equals. A plan within `GOOD_ENOUGH` of the lower bound ends the
   trying at once (on 10,000 tiles each try costs about 0.06 s);
2. local search, while the plan is more than `GOOD_ENOUGH` above the lower bound and time is left:
   take the robot that finishes last and try, one at a time, (a) handing one of its border tiles to
   a touching robot that finishes earlier and (b) handing a tile it waits for to the robot whose
   support it waits on; re-sequence (critical path, with and without helping) and keep the first
   move that lowers the makespan (or keeps it and lowers the waiting). Moves keep regions connected
   and non-empty, as in node trading. Stop when no move helps the last robot.
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

IMPROVEMENT_EPSILON = 1e-6  # s
GOOD_ENOUGH = 1.005  # makespan / strongest lower bound at which the search stops
MOVES_PER_ROUND = 24  # candidate moves tried for the last robot before giving up

HELP_FREELY = 10.0  # help margin (in tile costs) of the free-helping policy

# (name, policy, help margin): the first of equally good plans wins, so the more local go first
ALL_POLICIES = (
    ("critical-path", Policy.CRITICAL_PATH, None),
    ("max-slack", Policy.MAX_SLACK, None),
    ("critical-path+help", Policy.CRITICAL_PATH, 0.0),
    ("critical-path+help-freely", Policy.CRITICAL_PATH, HELP_FREELY),
)
SEARCH_POLICIES = (ALL_POLICIES[0], ALL_POLICIES[2], ALL_POLICIES[3])


@dataclass(frozen=True, eq=False)
class ImprovedPlan:
    owner: IntArray  # who places each tile
    orders: list[list[int]]
    result: SimulationResult
    policy: str
    moves: int
    helped: int
    evaluations: int
    start: str  # the name of the partition the plan grew from


def _better(a: SimulationResult, b: SimulationResult) -> bool:
    if a.makespan < b.makespan - IMPROVEMENT_EPSILON:
        return True
    same = a.makespan <= b.makespan + IMPROVEMENT_EPSILON
    return same and a.total_wait < b.total_wait - IMPROVEMENT_EPSILON


def best_sequencing(
    graph: AssemblyGraph,
    owner: IntArray,
    n_robots: int,
    distance: FloatArray,
    policies: tuple = ALL_POLICIES,
    good_enough: float = 0.0,
) -> tuple[Sequencing, SimulationResult, str, int]:
    """Orders by the policies, simulated, until one finishes within `good_enough`; the ones that
    finish first (then wait least), and how many policies were tried."""
    best = None
    tried = 0
    for name, policy, margin in policies:
        sequencing = sequence_tiles(graph, owner, n_robots, policy, distance, margin)
        result = sequencing.schedule if sequencing.schedule is not None else simulate_orders(graph, sequencing.orders)
        tried += 1
        if best is None or _better(result, best[1]):
            best = (sequencing, result, name)
        if best[1].makespan <= good_enough:
            break
    assert best is not None
    return (*best, tried)


def _candidate_moves(
    regions: RegionBorders, result: SimulationResult, orders: list[list[int]], late: int, owner: IntArray
) -> list[tuple[int, int]]:
    """(tile, taker) moves that may let the last robot finish earlier, most promising first."""
    finish = result.robot_finish
    cost = regions.cost
    moves: list[tuple[int, int]] = []
    # (b) a tile the last robot waits for goes to the robot placing the support it waits on
    waits = [(result.wait[t], t) for t in orders[late] if owner[t] == late]
    for wait, t in sorted(waits, reverse=True):
        if wait <= IMPROVEMENT_EPSILON:
            break
        supports = regions.graph.support_lists[t]
        if not supports:
            continue
        last = max(supports, key=lambda s: result.place_end[s])
        taker = int(owner[last])
        if taker != late and regions.counts[t].get(taker):
            moves.append((t, taker))
    # (a) a border tile of the last robot goes to a touching robot that finishes earlier
    for taker in sorted(regions.neighbor_regions(late), key=lambda r: finish[r]):
        room = finish[late] - finish[taker]
        if room <= IMPROVEMENT_EPSILON:
            break
        border = [t for t in regions.border.get((late, taker), ()) if cost[t] < room]
        border.sort(key=lambda t: (-regions.counts[t][taker], abs(cost[t] - 0.5 * room), t))
        moves.extend((t, taker) for t in border[:6])
    return moves


def improve_plan(
    graph: AssemblyGraph,
    partitions: Mapping[str, IntArray],
    n_robots: int,
    distance: FloatArray,
    time_limit: float,
    good_enough: float = 0.0,
    help_neighbours: bool = True,
    max_slack: bool = True,
) -> ImprovedPlan:
    """Best start among `partitions`, then local search (see the module docstring).

    `good_enough` (s): a makespan at which to stop searching (e.g. just above the lower bound).
    Without `help_neighbours` only policies that keep every robot to its region are used, so the
    regions stay connected. Without `max_slack` the paper's policy is not tried (on a 10,000-tile
    pyramid it ordered within 0.004% of critical path, at 0.1 s a try).
    """
    start_policies = ALL_POLICIES if help_neighbours else ALL_POLICIES[:2]
    if not max_slack:
        start_policies = tuple(entry for entry in start_policies if entry[1] is not Policy.MAX_SLACK)
    search_policies = SEARCH_POLICIES if help_neighbours else SEARCH_POLICIES[:1]
    deadline = time.perf_counter() + time_limit
    best = None
    evaluations = 0
    for name, candidate in partitions.items():
        sequencing, result, policy, sequenced = best_sequencing(
            graph, candidate, n_robots, distance, start_policies, good_enough
        )
        evaluations += sequenced
        if best is None or _better(result, best[1]):
            best = (sequencing, result, policy, name, candidate)
        if best[1].makespan <= good_enough:
            break  # the later starts cannot be much better: they are tried for harder structures
    assert best is not None
    sequencing, result, policy, start, partition = best
    moves = 0
    regions = RegionBorders(graph, partition, n_robots)
    while result.makespan > good_enough and time.perf_counter() < deadline:
        late = int(np.argmax(result.robot_finish))
        improved = False
        tried: set[tuple[int, int]] = set()
        for tile, taker in _candidate_moves(regions, result, sequencing.orders, late, sequencing.owner):
            if len(tried) >= MOVES_PER_ROUND or time.perf_counter() >= deadline:
                break
            giver = regions.owner[tile]
            if (tile, taker) in tried or giver == taker or not regions.can_leave(tile):
                continue
            tried.add((tile, taker))
            regions.move(tile, taker)
            trial_owner = np.array(regions.owner, dtype=np.int64)
            *trial, sequenced = best_sequencing(graph, trial_owner, n_robots, distance, search_policies)
            evaluations += sequenced
            if _better(trial[1], result):
                sequencing, result, policy = trial
                moves += 1
                improved = True
                break
            regions.move(tile, giver)
        if not improved:
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
