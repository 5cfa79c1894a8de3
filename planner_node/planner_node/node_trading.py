"""Node trading: balance the robots' workloads across region borders (paper section 2.1, step 2).

"This initial allocation strategy is then improved with a second phase of node trading to yield a
more balanced workload among the robots." A trade moves one border tile from a heavier region to a
touching lighter one. A tile of cost c moves from region i to region j only when c < W_i - W_j:
both new workloads then lie strictly between the old two, so the sum of squared workloads falls,
the heaviest workload never grows and the lightest never shrinks (the imbalance max/mean never gets
worse), and trading ends. It stops when no border tile can move that way.

Constraints of every trade:
* the giving region stays connected (the receiving one is, since the tile touches it): the tile's
  neighbours in its region must still reach each other without it. Searches started from each of
  them at once decide this locally, in time proportional to the smaller side; a search that runs
  past a budget refuses the trade (never a wrong "yes");
* no region is emptied;
* no precedence deadlock: a partition alone cannot deadlock (any partition can be executed in one
  team-wide order of the precedence DAG); deadlocks come from contradictory per-robot orders, and
  the sequencing step builds every order from one team-wide schedule, so none can arise there.

Work per trade is proportional to the size of the border between the two regions: the border
sets and workload sums are kept up to date incrementally.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterator
from dataclasses import dataclass
from heapq import heapify, heappop

import numpy as np
from numpy.typing import NDArray

from planner_node.assembly_graph import AssemblyGraph

IntArray = NDArray[np.int64]
FloatArray = NDArray[np.float64]

TRADE_MARGIN = 1e-6  # s
SEARCH_BUDGET = 64  # tile expansions a connectivity check may spend before refusing the trade



def imbalance(workloads: FloatArray | list[float]) -> float:
    """max / mean of the robots' workloads (1.0 is perfect balance; robots without tiles count)."""
    loads = np.asarray(workloads, dtype=float)
    if len(loads) == 0 or loads.sum() <= 0:
        return 1.0
    return float(loads.max() / loads.mean())


def workloads(graph: AssemblyGraph, owner: IntArray, n_robots: int) -> FloatArray:
    return np.bincount(owner, weights=graph.cost, minlength=n_robots)[:n_robots]


@dataclass(frozen=True, eq=False)
class TradingResult:
    owner: IntArray
    trades: int
    workload_before: FloatArray
    workload_after: FloatArray

    @property
    def imbalance_before(self) -> float:
        return imbalance(self.workload_before)

    @property
    def imbalance_after(self) -> float:
        return imbalance(self.workload_after)


def _neighbours_by_region(graph: AssemblyGraph, owner: IntArray, n_robots: int) -> Iterator[tuple[int, int, int]]:
    """(tile, region, how many of the tile's neighbours lie in the region) for every tile and
    every region next to it, counted as arrays (a 10k-tile structure has 150k neighbour pairs)."""
    rows, columns = graph.edge_ends
    regions = max(n_robots, int(owner.max()) + 1 if len(owner) else 0)
    keys, counts = np.unique(rows * regions + np.asarray(owner, dtype=np.int64)[columns], return_counts=True)
    return zip((keys // regions).tolist(), (keys % regions).tolist(), counts.tolist(), strict=True)


class RegionBorders:
    """Regions of the contact graph with their workloads and border sets, updated per move."""

    def __init__(
        self, graph: AssemblyGraph, owner: IntArray, n_robots: int, affinity: FloatArray | None = None
    ) -> None:
        self.graph = graph
        # affinity[r][t]: how far tile t is from robot r's region (seed distance); trades move the
        # tiles nearest to the taker relative to the giver first, so regions stay compact
        self.affinity = (
            [np.nan_to_num(row, posinf=1e12).tolist() for row in affinity] if affinity is not None else None
        )
        self.neighbors = graph.neighbor_lists
        self.cost = graph.cost.tolist()
        self.owner: list[int] = [int(o) for o in owner]
        self.n_robots = n_robots
        self.load = workloads(graph, owner, n_robots).tolist()
        self.size = np.bincount(owner, minlength=n_robots)[:n_robots].tolist()
        # counts[t][r]: how many neighbours of t lie in region r
        self.counts: list[dict[int, int]] = [{} for _ in range(len(graph))]
        self.border: dict[tuple[int, int], set[int]] = {}
        for t, r, count in _neighbours_by_region(graph, owner, n_robots):
            self.counts[t][r] = count
            mine = self.owner[t]
            if r != mine:
                self.border.setdefault((mine, r), set()).add(t)
        # Tiles refused leave, asked again only once a neighbour of theirs has moved. Trading asks
        # about the same few tiles thousands of times, and further moves hardly ever change the
        # answer (28 of 8,176 times on a 10k-tile cluster); a tile kept too long is a trade
        # missed, never a region split.
        self.refused: set[int] = set()

    def neighbor_regions(self, region: int) -> list[int]:
        return [r for r in range(self.n_robots) if r != region and self.border.get((region, r))]

    def can_leave(self, tile: int) -> bool:
        """True when `tile` can leave its region without disconnecting or emptying it."""
        region = self.owner[tile]
        if self.size[region] <= 1 or tile in self.refused:
            return False
        if self._connected_without(tile, region):
            return True
        self.refused.add(tile)
        return False

    def _connected_without(self, tile: int, region: int) -> bool:
        owner = self.owner
        inside = [u for u in self.neighbors[tile] if owner[u] == region]
        if len(inside) <= 1:
            return True
        neighbors = self.neighbors
        # the common case: the neighbours still meet within two steps of the tile
        near = set(inside)
        for u in inside:
            near.update(v for v in neighbors[u] if owner[v] == region)
        near.discard(tile)
        # the neighbours grouped by where they meet near the tile; usually that is one group
        search_of = {tile: -1}
        queues: list[deque[int]] = []
        for u in inside:
            if u in search_of:
                continue
            k = len(queues)
            search_of[u] = k
            stack, met = [u], [u]
            while stack:
                for v in neighbors[stack.pop()]:
                    if v in near and v not in search_of:
                        search_of[v] = k
                        stack.append(v)
                        met.append(v)
            queues.append(deque(met))
        if len(queues) == 1:
            return True
        # One breadth-first search from each group, advanced in turns: they stop as soon as
        # they have all met (still connected), or as soon as one of them runs out of tiles before
        # meeting the others (that part would be cut off). Either way the work is about the size
        # of the smaller side, not of the whole region; past a budget the answer is "no".
        parent = list(range(len(queues)))

        def root(k: int) -> int:
            while parent[k] != k:
                parent[k] = parent[parent[k]]
                k = parent[k]
            return k

        groups = len(queues)
        budget = SEARCH_BUDGET
        while True:
            budget -= len(queues)
            if budget < 0:
                return False  # undecided after a long search: refuse, so that no region ever splits
            for k, queue in enumerate(queues):
                # `parent[k] == k` says as much as `root(k) == k`, without a call
                if parent[k] != k and not queue:
                    continue
                if not queue:
                    return False  # search k (with all it met) is closed off from the others
                here = k if parent[k] == k else root(k)
                for v in neighbors[queue.popleft()]:
                    if owner[v] != region:
                        continue
                    other = search_of.get(v)
                    if other is None:
                        search_of[v] = here
                        queue.append(v)
                    elif other >= 0 and other != here:  # `here` is a root: no search meets itself
                        met = root(other)
                        if met != here:
                            parent[met] = here
                            groups -= 1
                            if groups == 1:
                                return True
                # a merged search keeps its own queue; queues of one group are advanced in turn
                if parent[k] != k:
                    r = root(k)
                    queues[r].extend(queue)
                    queue.clear()

    def move(self, tile: int, to: int) -> None:
        """Move `tile` to region `to`, updating workloads, sizes and borders."""
        owner, counts, border = self.owner, self.counts, self.border
        self.refused.difference_update(self.neighbors[tile])
        old = owner[tile]
        mine = counts[tile]
        for r, k in mine.items():
            if k and r != old:
                border[(old, r)].discard(tile)
        owner[tile] = to
        for r, k in mine.items():
            if k and r != to:
                border.setdefault((to, r), set()).add(tile)
        self.load[old] -= self.cost[tile]
        self.load[to] += self.cost[tile]
        self.size[old] -= 1
        self.size[to] += 1
        for u in self.neighbors[tile]:
            theirs = counts[u]
            home = owner[u]
            left = theirs[old] - 1
            if left:
                theirs[old] = left
            else:
                del theirs[old]
                if home != old:
                    border[(home, old)].discard(u)
            joined = theirs.get(to, 0) + 1
            theirs[to] = joined
            if joined == 1 and home != to:
                border.setdefault((home, to), set()).add(u)

    def best_trade(self, giver: int, taker: int) -> int | None:
        """The border tile of `giver` next to `taker` whose move lowers the imbalance most."""
        # a margin keeps rounding from trading a tile back and forth when its cost equals the gap
        gap = self.load[giver] - self.load[taker] - TRADE_MARGIN
        cost, counts = self.cost, self.counts
        candidates = [t for t in self.border.get((giver, taker), ()) if cost[t] < gap]
        if not candidates:
            return None
        half = 0.5 * gap
        if self.affinity is not None:
            near, far = self.affinity[taker], self.affinity[giver]
            ranked = [(near[t] - far[t], abs(cost[t] - half), t) for t in candidates]
        else:
            # most contact with the taker first, then the best balancing cost
            ranked = [(-counts[t][taker], abs(cost[t] - half), t) for t in candidates]
        # best first, as sorting would give them (the tile breaks ties), but only as far as needed:
        # the first tile or two usually may leave
        heapify(ranked)
        while ranked:
            t = heappop(ranked)[-1]
            if self.can_leave(t):
                return t
        return None


def centroid_affinity(graph: AssemblyGraph, owner: IntArray, n_robots: int) -> FloatArray:
    """Floor distance from every region's centre (by work) to every tile, (robots, n) in m."""
    xy = graph.centroids[:, :2]
    weight = np.bincount(owner, weights=graph.cost, minlength=n_robots)[:n_robots]
    centre = np.column_stack([
        np.bincount(owner, weights=graph.cost * xy[:, k], minlength=n_robots)[:n_robots] for k in (0, 1)
    ]) / np.maximum(weight, 1e-12)[:, None]
    return np.linalg.norm(xy[None, :, :] - centre[:, None, :], axis=2)


def trade_nodes(
    graph: AssemblyGraph,
    owner: IntArray,
    n_robots: int,
    affinity: FloatArray | None = None,
    max_trades: int | None = None,
) -> TradingResult:
    """Trade border tiles from heavier to lighter regions until no trade lowers the imbalance.

    `affinity` (robots, n): distance of each tile from each robot's region (its seed); among the
    tiles that may move, the one nearest the taker relative to the giver goes first.
    """
    before = workloads(graph, owner, n_robots)
    regions = RegionBorders(graph, owner, n_robots, affinity)
    limit = max_trades if max_trades is not None else 20 * len(graph) + 100
    trades = 0
    # (giver, taker) pairs found without a trade since either region last changed. A trade between
    # two other regions changes neither region's tiles, workload or common border, so the answer
    # stays the same: asking again (a connectivity search per candidate) is what made trading slow.
    no_trade: set[tuple[int, int]] = set()
    while trades < limit:
        traded = False
        load = regions.load
        for giver in sorted(range(n_robots), key=lambda r: -load[r]):
            for taker in sorted(regions.neighbor_regions(giver), key=lambda r: load[r]):
                if load[taker] >= load[giver]:
                    break
                if (giver, taker) in no_trade:
                    continue
                tile = regions.best_trade(giver, taker)
                if tile is None:
                    no_trade.add((giver, taker))
                    continue
                regions.move(tile, taker)
                no_trade = {pair for pair in no_trade if giver not in pair and taker not in pair}
                trades += 1
                traded = True
                break
            if traded:
                break
        if not traded:
            break
    final = np.array(regions.owner, dtype=np.int64)
    return TradingResult(final, trades, before, workloads(graph, final, n_robots))
