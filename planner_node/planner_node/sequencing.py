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

from dataclasses import dataclass
from enum import Enum
from heapq import heappop, heappush
from weakref import WeakKeyDictionary

import numpy as np
from numpy.typing import NDArray

from planner_node.assembly_graph import AssemblyGraph
from planner_node.schedule_sim import SimulationResult

IntArray = NDArray[np.int64]
FloatArray = NDArray[np.float64]
Heap = list[tuple]  # a heapq heap of tuples whose last element is the tile or robot


class Policy(Enum):
    MAX_SLACK = "max-slack"
    CRITICAL_PATH = "critical-path"


@dataclass(frozen=True, eq=False)
class Sequencing:
    orders: list[list[int]]  # graph indices per robot, in placement order
    owner: IntArray  # who places each tile (differs from the partition only after helping)
    helped: int  # tiles placed by a robot other than their region's
    # the team simulation of `orders` when the pass itself is it (no robot ever started a tile
    # later than it was back at its caches), else None: simulate_orders works it out
    schedule: SimulationResult | None = None


_bottom_levels: WeakKeyDictionary[AssemblyGraph, list[float]] = WeakKeyDictionary()


def bottom_levels(graph: AssemblyGraph) -> list[float]:
    """Longest time from the start of each tile's placement to the end of the build (s).

    Worked out once per graph (every critical-path sequencing of a plan asks for it); the list
    returned is shared, not to be changed."""
    if graph not in _bottom_levels:
        _bottom_levels[graph] = _longest_paths_to_the_end(graph)
    return _bottom_levels[graph]


def _longest_paths_to_the_end(graph: AssemblyGraph) -> list[float]:
    place = graph.place.tolist()
    back = graph.back.tolist()
    dependents = graph.dependent_lists
    level = [0.0] * len(graph)
    for t in reversed(graph.topological_order.tolist()):
        longest = back[t]  # after the last tile its robot still travels back
        for d in dependents[t]:
            if level[d] > longest:
                longest = level[d]
        level[t] = place[t] + longest
    return level


def region_adjacency(graph: AssemblyGraph, owner: IntArray, n_robots: int) -> list[set[int]]:
    """Which robots' regions touch (through any contact)."""
    rows, columns = graph.edge_ends
    a, b = owner[rows], owner[columns]
    touching = [set() for _ in range(n_robots)]
    for r, s in set(zip(a[a != b].tolist(), b[a != b].tolist(), strict=True)):
        touching[r].add(s)
    return touching


def foreign_dependents(graph: AssemblyGraph, owner: list[int]) -> list[int]:
    """How many of the tiles resting on each tile belong to another robot."""
    dependents = graph.dependent_lists
    return [sum(1 for d in dependents[t] if owner[d] != owner[t]) for t in range(len(graph))]


def sequence_tiles(
    graph: AssemblyGraph,
    owner: IntArray,
    n_robots: int,
    policy: Policy,
    distance: FloatArray | None = None,
    help_margin: float | None = None,
) -> Sequencing:
    """Every robot's tiles (graph indices) in placement order; see the module docstring."""
    return TeamSequencer(graph, owner, n_robots, policy, distance, help_margin).run()


class TeamSequencer:
    """One list-scheduling pass over the whole team under the time model (section 2.1, step 3).

    Each robot keeps two heaps of candidate tiles: `waiting`, keyed by when the tile could be
    placed without waiting (max slack: by the paper's key), and `ready` (critical path), the tiles
    placeable now, by priority. A tile taken over by a helper stays in its old robot's heaps and
    is skipped there because its owner changed; that is cheaper than deleting it from a heap.
    """

    def __init__(
        self,
        graph: AssemblyGraph,
        owner: IntArray,
        n_robots: int,
        policy: Policy,
        distance: FloatArray | None,
        help_margin: float | None,
    ) -> None:
        n = len(graph)
        self.n_robots = n_robots
        self.owner = [int(o) for o in owner]
        # plain lists: the pass reads single elements in tight loops, where numpy is slow
        self.pick_time = graph.pick.tolist()
        self.travel_time = graph.travel.tolist()  # one way, cache to tile
        self.back_time = graph.back.tolist()  # tile to a cache
        self.place_time = graph.place.tolist()
        self.first_trip = graph.first_trips(n_robots)  # to the first tile's cache, from where the robot stands
        self.cost, self.layer = graph.cost.tolist(), graph.layer.tolist()
        self.distance = (distance if distance is not None else np.zeros(n)).tolist()
        self.supports, self.dependents = graph.support_lists, graph.dependent_lists
        self.critical_path = policy is Policy.CRITICAL_PATH
        self.helping = help_margin is not None and self.critical_path
        self.help_margin = help_margin if help_margin is not None else 0.0
        self.bottom_level = bottom_levels(graph) if self.critical_path else []
        # each tile's priority among the ready ones (most urgent first), made once: nearly every
        # tile passes through a `ready` heap
        self.ready_key = [
            (-level, layer, near, t)
            for t, (level, layer, near) in enumerate(zip(self.bottom_level, self.layer, self.distance, strict=True))
        ] if self.critical_path else []
        self.foreign_dependents = [] if self.critical_path else foreign_dependents(graph, self.owner)
        self.neighbours = region_adjacency(graph, owner, n_robots) if self.helping else []
        # the robots whose regions do not touch each robot's (sets: who is asked first among
        # equally urgent tiles follows their order)
        self.others = [set(range(n_robots)) - near - {r} for r, near in enumerate(self.neighbours)]

        self.waiting: list[Heap] = [[] for _ in range(n_robots)]
        self.ready: list[Heap] = [[] for _ in range(n_robots)]
        self.supports_end = [0.0] * n  # latest placement end of the tile's supports scheduled so far
        self.unscheduled_supports = [len(s) for s in self.supports]
        self.scheduled = [False] * n
        self.remaining_work = [0.0] * n_robots  # cost of each robot's tiles not yet scheduled
        for t in range(n):
            self.remaining_work[self.owner[t]] += self.cost[t]
        self.orders: list[list[int]] = [[] for _ in range(n_robots)]
        self.free_at = [0.0] * n_robots  # when each robot is back at its caches
        self.idle = [False] * n_robots  # found nothing to do; woken when a tile of its becomes ready
        self.robots_free: Heap = [(0.0, r) for r in range(n_robots)]  # (time, robot) events
        self.helped = 0
        # The pass's own times, while they are the simulation's (see `schedule`): until some robot
        # starts a tile later than it is back at its caches (it was idle in between), a robot
        # following the orders as fixed does exactly what the pass did, to the last bit.
        self.delayed = False
        nan = float("nan")
        self.start, self.arrive, self.place_start = [nan] * n, [nan] * n, [nan] * n
        self.place_end, self.finish, self.stood = [nan] * n, [nan] * n, [nan] * n
        # s from a robot's last placement back to a cache: after waiting by it, the robot still walks that
        self.last_back = [0.0] * n_robots
        self.busy, self.wait = [0.0] * n_robots, [0.0] * n_robots  # summed in each robot's order

    def run(self) -> Sequencing:
        """Schedule every tile, robot by robot as each comes back to its caches."""
        self.offer_floor_tiles()
        robots_free, idle, free_at = self.robots_free, self.idle, self.free_at
        choose, place, release_dependents = self.choose, self.place, self.release_dependents
        while robots_free:
            now, robot = heappop(robots_free)
            tile = choose(robot, now)
            if tile is None:
                idle[robot] = True
                continue
            end = place(tile, robot, now)
            release_dependents(tile, end, now)
            heappush(robots_free, (free_at[robot], robot))
        if sum(len(o) for o in self.orders) != len(self.owner):
            raise RuntimeError("sequencing left tiles unscheduled: the support relation has a cycle")
        return Sequencing(self.orders, np.array(self.owner, dtype=np.int64), self.helped, self.schedule())

    def offer_floor_tiles(self) -> None:
        """Tiles on the floor wait for nothing: every robot may start with one."""
        for t, below in enumerate(self.supports):
            if not below:
                self.offer(t)

    def offer(self, t: int) -> None:
        """Make tile t, whose supports are all scheduled, a candidate of its robot."""
        waiting = self.waiting[self.owner[t]]
        if self.critical_path:
            heappush(waiting, (self.supports_end[t], t))
        else:  # floor tiles have nothing to wait for, so they go first
            slack_key = self.supports_end[t] - self.travel_time[t] if self.supports[t] else float("-inf")
            heappush(waiting, (slack_key, -self.foreign_dependents[t], self.layer[t], self.distance[t], t))

    def is_current(self, entry: tuple, robot: int) -> bool:
        """Whether a heap entry of `robot` still names one of its unscheduled tiles."""
        t = entry[-1]
        return not self.scheduled[t] and self.owner[t] == robot

    def choose(self, robot: int, now: float) -> int | None:
        """The robot's next tile by the policy, or None when it has nothing left to place."""
        if not self.critical_path:
            waiting = self.waiting[robot]
            return heappop(waiting)[-1] if waiting else None
        t = self.best_ready(robot, now)
        if t is None and self.helping:
            t = self.tile_to_help_with(robot, now)
        if t is None:
            t = self.least_wait(robot)
        return t

    def best_ready(self, robot: int, now: float) -> int | None:
        """The robot's most urgent tile it can place at `now` without waiting."""
        waiting, ready = self.waiting[robot], self.ready[robot]
        scheduled, owner = self.scheduled, self.owner  # `is_current` inlined: this runs for every choice
        last_placed = now - self.last_back[robot]  # it may set out once the supports are placed by then
        while waiting:
            supports_end, t = waiting[0]
            if supports_end > last_placed and not scheduled[t] and owner[t] == robot:
                break
            heappop(waiting)
            if not scheduled[t] and owner[t] == robot:
                heappush(ready, self.ready_key[t])
        while ready and (scheduled[ready[0][-1]] or owner[ready[0][-1]] != robot):
            heappop(ready)
        return ready[0][-1] if ready else None

    def least_wait(self, robot: int) -> int | None:
        """The robot's tile that could be placed soonest, when none can be placed now."""
        waiting = self.waiting[robot]
        while waiting and not self.is_current(waiting[0], robot):
            heappop(waiting)
        return waiting[0][-1] if waiting else None

    def tile_to_help_with(self, robot: int, now: float) -> int | None:
        """The most urgent tile another robot could place now, if that robot would still finish
        after the helper; neighbouring robots first, so that the helper stays near its region."""
        mine = now + self.remaining_work[robot]
        best = None
        for group in (self.neighbours[robot], self.others[robot]):
            for other in group:
                t = self.best_ready(other, now)
                if t is None or not self.worth_helping(t, mine=mine, helped=other, now=now):
                    continue
                if best is None or self.bottom_level[t] > self.bottom_level[best]:
                    best = t
            if best is not None:
                return best
        return None

    def worth_helping(self, t: int, *, mine: float, helped: int, now: float) -> bool:
        """Whether the helped robot, without tile t, still finishes after the helper with it."""
        cost = self.cost[t]
        theirs = max(self.free_at[helped], now) + self.remaining_work[helped]
        return mine + cost <= theirs - cost + self.help_margin * cost

    def place(self, t: int, robot: int, now: float) -> float:
        """Commit tile t to `robot`, leaving its caches at `now`; when the placement ends (s)."""
        if self.owner[t] != robot:
            self.take_over(t, robot=robot)
        self.scheduled[t] = True
        self.remaining_work[robot] -= self.cost[t]
        if now != self.free_at[robot]:
            self.delayed = True
        leaves = self.supports_end[t] + self.last_back[robot]  # as `schedule_sim` works it out, bit for bit
        stood = leaves - now if leaves > now else 0.0
        now += stood
        if not self.orders[robot]:
            now += self.first_trip[robot][t]
        arrive = now + self.pick_time[t] + self.travel_time[t]
        end = arrive + self.place_time[t]
        self.free_at[robot] = end + self.back_time[t]
        self.last_back[robot] = self.back_time[t]
        self.orders[robot].append(t)
        if not self.delayed:  # as schedule_sim.simulate_orders works them out
            self.start[t], self.arrive[t], self.place_start[t] = now, arrive, arrive
            self.place_end[t], self.finish[t], self.stood[t] = end, end + self.back_time[t], stood
            self.wait[robot] += stood
            self.busy[robot] += self.cost[t]
        return end

    def schedule(self) -> SimulationResult | None:
        """The simulation of the orders, when the pass was it (see __init__)."""
        if self.delayed:
            return None
        return SimulationResult(
            start=np.array(self.start),
            arrive=np.array(self.arrive),
            place_start=np.array(self.place_start),
            place_end=np.array(self.place_end),
            finish=np.array(self.finish),
            wait=np.array(self.stood),
            robot_busy=np.array(self.busy),
            robot_wait=np.array(self.wait),
            robot_finish=np.array(self.free_at),
            blocked=(),
        )

    def take_over(self, t: int, *, robot: int) -> None:
        """Hand tile t to the robot that helps with it."""
        self.remaining_work[self.owner[t]] -= self.cost[t]
        self.remaining_work[robot] += self.cost[t]
        self.owner[t] = robot
        self.helped += 1

    def release_dependents(self, t: int, end: float, now: float) -> None:
        """Offer the tiles that tile t was the last unscheduled support of, placed by `end`, and
        wake the idle robots that may now place them (at `now`)."""
        supports_end, unscheduled, owner, idle = self.supports_end, self.unscheduled_supports, self.owner, self.idle
        critical_path, waiting = self.critical_path, self.waiting
        for d in self.dependents[t]:
            if end > supports_end[d]:
                supports_end[d] = end
            unscheduled[d] -= 1
            if unscheduled[d] == 0:
                if critical_path:  # `offer` inlined: this runs for nearly every tile
                    heappush(waiting[owner[d]], (supports_end[d], d))
                else:
                    self.offer(d)
                if idle[owner[d]]:
                    self.wake(owner[d], now)
                if self.helping and True in idle:  # an idle robot may now help with the new tile
                    for k in range(self.n_robots):
                        if idle[k]:
                            self.wake(k, now)

    def wake(self, robot: int, now: float) -> None:
        """An idle robot chooses again at `now` (or when it is back, if later). The order robots
        are woken in does not matter: the heap orders them by (time, robot)."""
        self.idle[robot] = False
        heappush(self.robots_free, (max(self.free_at[robot], now), robot))
