"""A lower bound on the makespan of any plan (an addition to paper section 2.1, which reports none).

No plan for N robots can finish before either

* the critical path: along every chain of supports, a robot sets out for a tile only once its
  supports are placed, then picks, carries and places it, and the robot of the last tile still has
  to walk back (same phases as `schedule_sim`); or
* the total work divided among the robots: every robot's busy time is the sum of its tiles'
  costs, so the busiest robot works at least total / N.

The planner reports every plan's makespan divided by this bound (1.0 is optimal). With few tiles
per robot a third bound is often higher, and explains why no plan gets near the first two: the
robot with the most tiles places at least ceil(n / N) of them, so it works at least as long as the
ceil(n / N) cheapest tiles take (`tile_count`; reported beside the bound, not part of it).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planner_node.assembly_graph import AssemblyGraph


@dataclass(frozen=True)
class MakespanBound:
    critical_path: float  # s
    work_per_robot: float  # s, total work / N
    tile_count: float = 0.0  # s, the ceil(n / N) cheapest tiles (see the module docstring)

    @property
    def value(self) -> float:
        return max(self.critical_path, self.work_per_robot)

    @property
    def strongest(self) -> float:
        """The highest of all three bounds (still a lower bound on any plan's makespan)."""
        return max(self.value, self.tile_count)


def critical_path(graph: AssemblyGraph) -> float:
    """Longest chain of support placements under the time model, with the final trip back (s)."""
    earliest_end = [0.0] * len(graph)
    head = (graph.pick + graph.travel).tolist()
    place = graph.place.tolist()
    supports = graph.support_lists
    for t in graph.topological_order.tolist():
        supported = 0.0  # its robot sets out once the last of its supports is placed
        for s in supports[t]:
            if earliest_end[s] > supported:
                supported = earliest_end[s]
        earliest_end[t] = supported + head[t] + place[t]
    tail = [e + back for e, back in zip(earliest_end, graph.back.tolist(), strict=True)]
    return max(tail, default=0.0)


def makespan_lower_bound(graph: AssemblyGraph, n_robots: int) -> MakespanBound:
    """max(critical path, total work / n_robots) for `graph` (n_robots >= 1)."""
    if n_robots < 1:
        raise ValueError("the lower bound needs at least one robot")
    per_robot = -(-len(graph) // n_robots)
    cheapest = float(np.sort(graph.cost)[:per_robot].sum()) if len(graph) else 0.0
    return MakespanBound(critical_path(graph), graph.total_work / n_robots, cheapest)
