"""Sequencing: each robot's placement order (paper section 2.1, step 3).

"The last step of this approach is the generation of an assembly sequence for each robot that
minimizes the time a robot must wait for the placement of supporting tile by another robot. This
is achieved by maximizing the time between a placement and the placements of any supporting
tiles."

Every ordering here is built by one list-scheduling pass over the whole team under the time model
(the phases of `schedule_sim`): whenever a robot is back at its caches it chooses its next tile
among those whose supports have all been scheduled (by any robot), and the choice is committed.
Because every robot's order is cut from one team-wide schedule that respects the support relation,
the orders can never deadlock; and when the robots then execute them as fixed orders
(`schedule_sim`), no placement happens later than in this pass.

The choice rule is the policy:

* `MAX_SLACK` (the paper's rule): the tile whose supports are placed longest before it would be
  placed, i.e. the largest time between the supports' placement and its own; tiles on the floor
  (nothing to wait for) first. Ties: tiles that other robots' tiles rest on first (so that other
  robots wait less), then lower layers, then tiles nearer the robot's starting tile.
* `CRITICAL_PATH` (ours, beyond the paper): among tiles the robot can place without waiting, the
  one with the longest chain of work still resting on it (its bottom level in the precedence DAG
  under the time model), as in list scheduling with critical-path priority; when every candidate
  would wait, the one that waits least.

With `help_margin` (critical path only), a robot that would otherwise wait takes the most urgent
tile another robot could place right now, robots next to it first, when that robot is projected to
finish later than the helper even after giving the tile away, give or take `help_margin` times
the tile's cost (0: strictly later; a large margin: help whenever there is something to do). The
partition then changes: the returned owners say who places what.
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass
from enum import Enum

import numpy as np
from numpy.typing import NDArray

from planner_node.assembly_graph import AssemblyGraph

IntArray = NDArray[np.int64]
FloatArray = NDArray[np.float64]


class Policy(Enum):
    MAX_SLACK = "max-slack"
    CRITICAL_PATH = "critical-path"


@dataclass(frozen=True, eq=False)
class Sequencing:
    orders: list[list[int]]  # graph indices per robot, in placement order
    owner: IntArray  # who places each tile (differs from the partition only after helping)
    helped: int  # tiles placed by a robot other than their region's


def bottom_levels(graph: AssemblyGraph) -> list[float]:
    """Longest time from the start of each tile's placement to the end of the build (s)."""
    place = graph.place.tolist()
    travel = graph.travel.tolist()
    dependents = graph.dependent_lists
    level = [0.0] * len(graph)
    for t in reversed(graph.topological_order.tolist()):
        level[t] = place[t] + max(travel[t], max((level[d] for d in dependents[t]), default=0.0))
    return level


def region_adjacency(graph: AssemblyGraph, owner: IntArray, n_robots: int) -> list[set[int]]:
    """Which robots' regions touch (through any contact)."""
    coo = graph.adjacency.tocoo()
    a, b = owner[coo.row], owner[coo.col]
    touching = [set() for _ in range(n_robots)]
    for r, s in set(zip(a[a != b].tolist(), b[a != b].tolist(), strict=True)):
        touching[r].add(s)
    return touching


def sequence_tiles(
    graph: AssemblyGraph,
    owner: IntArray,
    n_robots: int,
    policy: Policy,
    distance: FloatArray | None = None,
    help_margin: float | None = None,
) -> Sequencing:
    """Every robot's tiles (graph indices) in placement order; see the module docstring."""
    n = len(graph)
    owner_list = [int(o) for o in owner]
    pick = graph.pick.tolist()
    travel = graph.travel.tolist()
    place = graph.place.tolist()
    cost = graph.cost.tolist()
    layer = graph.layer.tolist()
    near = (distance if distance is not None else np.zeros(n)).tolist()
    supports = graph.support_lists
    dependents = graph.dependent_lists
    critical = policy is Policy.CRITICAL_PATH
    helping = help_margin is not None and critical
    margin = help_margin if help_margin is not None else 0.0
    level = bottom_levels(graph) if critical else []
    outside = [] if critical else [
        sum(1 for d in dependents[t] if owner_list[d] != owner_list[t]) for t in range(n)
    ]
    touching = region_adjacency(graph, owner, n_robots) if helping else []

    # per robot: `waiting` holds candidates keyed by when they could be placed without waiting
    # (max slack: by the paper's key), `ready` (critical path) those placeable now, by priority.
    # A tile taken by a helper stays in its old heaps and is skipped there (owner changed).
    waiting: list[list[tuple]] = [[] for _ in range(n_robots)]
    ready: list[list[tuple]] = [[] for _ in range(n_robots)]
    supports_ready = [0.0] * n  # latest placement end of the tile's supports scheduled so far
    unscheduled = [len(s) for s in supports]
    done = [False] * n
    remaining = [0.0] * n_robots  # cost of each robot's tiles not yet scheduled
    for t in range(n):
        remaining[owner_list[t]] += cost[t]

    def offer(t: int) -> None:
        r = owner_list[t]
        if critical:
            heapq.heappush(waiting[r], (supports_ready[t] - travel[t] - pick[t], t))
        else:
            slack_key = supports_ready[t] - travel[t] if supports[t] else float("-inf")
            heapq.heappush(waiting[r], (slack_key, -outside[t], layer[t], near[t], t))

    def valid(entry: tuple, r: int) -> bool:
        t = entry[-1]
        return not done[t] and owner_list[t] == r

    def best_ready(r: int, now: float) -> int | None:
        pending, best = waiting[r], ready[r]
        while pending and (pending[0][0] <= now or not valid(pending[0], r)):
            entry = heapq.heappop(pending)
            if valid(entry, r):
                t = entry[1]
                heapq.heappush(best, (-level[t], layer[t], near[t], t))
        while best and not valid(best[0], r):
            heapq.heappop(best)
        return best[0][-1] if best else None

    def least_wait(r: int) -> int | None:
        pending = waiting[r]
        while pending and not valid(pending[0], r):
            heapq.heappop(pending)
        return pending[0][-1] if pending else None

    def help_someone(r: int, now: float) -> int | None:
        mine = now + remaining[r]
        best = None
        for group in (touching[r], set(range(n_robots)) - touching[r] - {r}):
            for v in group:
                t = best_ready(v, now)
                if t is None:
                    continue
                theirs = max(free[v], now) + remaining[v]
                if mine + cost[t] > theirs - cost[t] + margin * cost[t]:
                    continue
                if best is None or level[t] > level[best]:
                    best = t
            if best is not None:
                return best
        return None

    def choose(r: int, now: float) -> int | None:
        if not critical:
            pending = waiting[r]
            return heapq.heappop(pending)[-1] if pending else None
        t = best_ready(r, now)
        if t is None and helping:
            t = help_someone(r, now)
        if t is None:
            t = least_wait(r)
        return t

    for t in range(n):
        if not supports[t]:
            offer(t)
    orders: list[list[int]] = [[] for _ in range(n_robots)]
    free = [0.0] * n_robots
    idle = [False] * n_robots
    events = [(0.0, r) for r in range(n_robots)]
    helped = 0
    while events:
        now, r = heapq.heappop(events)
        t = choose(r, now)
        if t is None:
            idle[r] = True
            continue
        if owner_list[t] != r:
            remaining[owner_list[t]] -= cost[t]
            remaining[r] += cost[t]
            owner_list[t] = r
            helped += 1
        done[t] = True
        remaining[r] -= cost[t]
        arrive = now + pick[t] + travel[t]
        start = supports_ready[t] if supports_ready[t] > arrive else arrive
        end = start + place[t]
        free[r] = end + travel[t]
        orders[r].append(t)
        woken: set[int] = set()
        for d in dependents[t]:
            if end > supports_ready[d]:
                supports_ready[d] = end
            unscheduled[d] -= 1
            if unscheduled[d] == 0:
                offer(d)
                woken.add(owner_list[d])
                if helping:
                    woken.update(k for k in range(n_robots) if idle[k])
        for k in woken:
            if idle[k]:
                idle[k] = False
                heapq.heappush(events, (max(free[k], now), k))
        heapq.heappush(events, (free[r], r))
    if sum(len(o) for o in orders) != n:
        raise RuntimeError("sequencing left tiles unscheduled: the support relation has a cycle")
    return Sequencing(orders, np.array(owner_list, dtype=np.int64), helped)
