"""Discrete-event simulation of the whole team executing a plan (paper section 2.1, step 4).

Paper section 2.1 asks for assembly sequences that "minimize the time a robot must wait for the
placement of a supporting tile by another robot"; this module measures exactly that. Each robot
works through its tiles in order; one tile is one round trip of the time model
(`TimeModel.tile_cost`):

    start         the robot is at the cache of the tile's type and picks the tile (pick time)
    arrive        it has carried the tile to the structure (travel time)
    place_start   it places the tile (= arrive)
    place_end     the tile is placed: tiles resting on it may be placed from now on
    finish        the robot is back at a cache (return time): it starts its next tile

A robot sets out for a tile only once every support of it is placed, as the robots do (section
3.1: they "wait for the placement of a missing support tile by another robot before placing their
parts"; a robot's `place_tile` goal is sent when its supports are placed, and its first phase is
the drive to the cache). It waits where it placed its last tile, so after the wait it still walks
back to the cache: it starts at max(back at the cache, last support placed + that walk). Charging
the wait at the structure, tile in hand, instead made gate_9's plan for 3 robots 23% too short:
along its chain of five tiles on top of each other every link costs a whole trip.

A robot starts at t = 0 at the cache of its first tile (the paper's robots start at their parts
caches), or, when the graph knows where the robots stand (`AssemblyGraph.first_trip`), drives
there first. A robot's busy time is exactly its workload (the sum of its tiles' costs), and its
finish time is that trip + workload + wait. The makespan is the time the last
robot is back from its last tile. A plan whose orders contradict each other (robot A waits for a
tile that robot B only places after a tile waiting for A) deadlocks: the simulation stops and
names the tiles each blocked robot is waiting to place.

`simulate_orders` works on graph indices and runs in O(tiles + supports); `simulate_plan` takes
tile ids and robot names and returns a `TeamSchedule` with per-robot, per-tile times (for the
assembly robots' progress estimates and schedule charts).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import NDArray

from planner_node.assembly_graph import AssemblyGraph, build_graph
from tiling_assembly.structure import Structure
from tiling_assembly.time_model import TimeModel

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class SimulationResult:
    """Times per tile index (NaN where a tile was never placed) and per robot."""

    start: FloatArray
    arrive: FloatArray
    place_start: FloatArray
    place_end: FloatArray
    finish: FloatArray
    wait: FloatArray  # s, per tile: how long its robot stood before setting out for it (supports)
    robot_busy: FloatArray  # s, sum of the robot's tile costs that it completed
    robot_wait: FloatArray  # s, time spent standing until the supports of its next tile were placed
    robot_finish: FloatArray  # s, back at the cache after its last tile
    blocked: tuple[int, ...]  # indices of the tiles blocked robots wait to place (deadlock)

    @property
    def completed(self) -> bool:
        return not self.blocked

    @property
    def makespan(self) -> float:
        return float(self.robot_finish.max()) if len(self.robot_finish) else 0.0

    @property
    def total_wait(self) -> float:
        return float(self.robot_wait.sum())


def simulate_orders(graph: AssemblyGraph, orders: Sequence[Sequence[int]]) -> SimulationResult:
    """Simulate robots executing `orders` (graph indices, one sequence per robot).

    Every tile index may appear at most once over all orders (ValueError otherwise). Tiles of the
    graph that no order contains are treated as never placed: tiles resting on them block.
    """
    n = len(graph)
    seen = [False] * n  # a list: numpy's element access is slow in a Python loop
    for order in orders:
        for t in order:
            if seen[t]:
                raise ValueError(f"tile {graph.tile_ids[t]} appears more than once in the orders")
            seen[t] = True

    pick, travel, back, place = graph.pick.tolist(), graph.travel.tolist(), graph.back.tolist(), graph.place.tolist()
    supports = graph.support_lists
    dependents = graph.dependent_lists
    nan = float("nan")
    start, arrive, place_start = [nan] * n, [nan] * n, [nan] * n
    place_end, finish, stood = [nan] * n, [nan] * n, [nan] * n
    unplaced_supports = [len(s) for s in supports]
    waiting_robot: dict[int, int] = {}  # tile index -> robot blocked with it at the head

    robots = len(orders)
    first_trip = graph.first_trips(robots)
    clock = [0.0] * robots
    busy = [0.0] * robots
    wait = [0.0] * robots
    position = [0] * robots
    runnable = list(range(robots - 1, -1, -1))
    round_trip = graph.cost.tolist()
    while runnable:
        r = runnable.pop()
        order = orders[r]
        k, now, length = position[r], clock[r], len(order)
        waited, worked = wait[r], busy[r]  # the robot's sums, added to in the same order
        while k < length:
            t = order[k]
            if unplaced_supports[t]:
                waiting_robot[t] = r
                break
            ready = 0.0  # when the last support is placed (times are never negative)
            for s in supports[t]:
                if place_end[s] > ready:
                    ready = place_end[s]
            leaves = ready if k == 0 else ready + back[order[k - 1]]  # from where it placed its last tile
            stood[t] = leaves - now if leaves > now else 0.0
            waited += stood[t]
            now += stood[t]
            if k == 0:
                now += first_trip[r][t]
            start[t] = now
            arrived = now + pick[t] + travel[t]
            arrive[t] = place_start[t] = arrived
            end = arrived + place[t]
            place_end[t] = end
            now = end + back[t]
            finish[t] = now
            worked += round_trip[t]
            k += 1
            for d in dependents[t]:
                unplaced_supports[d] -= 1
                if unplaced_supports[d] == 0 and d in waiting_robot:
                    runnable.append(waiting_robot.pop(d))
        position[r], clock[r], wait[r], busy[r] = k, now, waited, worked

    blocked = tuple(orders[r][position[r]] for r in range(robots) if position[r] < len(orders[r]))
    return SimulationResult(
        start=np.array(start),
        arrive=np.array(arrive),
        place_start=np.array(place_start),
        place_end=np.array(place_end),
        finish=np.array(finish),
        wait=np.array(stood),
        robot_busy=np.array(busy),
        robot_wait=np.array(wait),
        robot_finish=np.array(clock),
        blocked=blocked,
    )


@dataclass(frozen=True)
class TileTiming:
    """When one tile is handled (s from the start of the build); see the module docstring."""

    tile_id: int
    robot: str
    start: float
    arrive: float
    place_start: float
    place_end: float
    finish: float
    wait: float  # s, stood before setting out for it: its supports were not yet placed


@dataclass(frozen=True)
class RobotTimeline:
    """One robot's tiles in order with their times, its busy time, waiting time and finish."""

    robot: str
    tiles: tuple[TileTiming, ...]
    busy: float
    wait: float
    finish: float


@dataclass(frozen=True)
class TeamSchedule:
    """The simulated build: every robot's timeline, the makespan, and any deadlock."""

    robots: tuple[RobotTimeline, ...]
    makespan: float
    blocked_tiles: tuple[int, ...]  # tile ids blocked robots wait to place; empty when complete

    @property
    def completed(self) -> bool:
        return not self.blocked_tiles

    @property
    def total_wait(self) -> float:
        return sum(r.wait for r in self.robots)

    @cached_property
    def _by_tile(self) -> dict[int, TileTiming]:
        return {t.tile_id: t for r in self.robots for t in r.tiles}

    def timing(self, tile_id: int) -> TileTiming:
        """Times of one tile (KeyError for a tile no robot places before a deadlock)."""
        return self._by_tile[tile_id]


def team_schedule(
    graph: AssemblyGraph,
    robot_names: Sequence[str],
    orders: Sequence[Sequence[int]],
    result: SimulationResult,
) -> TeamSchedule:
    """Package an index-level simulation result with tile ids and robot names."""
    timelines = []
    # plain lists: reading numpy arrays element by element is slow for 10,000 tiles
    ids, start, arrive = graph.tile_ids.tolist(), result.start.tolist(), result.arrive.tolist()
    place_start, place_end, finish = result.place_start.tolist(), result.place_end.tolist(), result.finish.tolist()
    stood = result.wait.tolist()
    for name, order, busy, wait, end in zip(
        robot_names, orders, result.robot_busy, result.robot_wait, result.robot_finish, strict=True
    ):
        tiles = tuple(
            TileTiming(
                tile_id=ids[t],
                robot=name,
                start=start[t],
                arrive=arrive[t],
                place_start=place_start[t],
                place_end=place_end[t],
                finish=finish[t],
                wait=stood[t],
            )
            for t in order
            if not math.isnan(place_end[t])
        )
        timelines.append(RobotTimeline(name, tiles, float(busy), float(wait), float(end)))
    return TeamSchedule(
        robots=tuple(timelines),
        makespan=result.makespan,
        blocked_tiles=tuple(int(graph.tile_ids[t]) for t in result.blocked),
    )


def simulate_plan(
    structure: Structure,
    time_model: TimeModel,
    orders: Mapping[str, Sequence[int]],
    graph: AssemblyGraph | None = None,
) -> TeamSchedule:
    """Simulate robots (name -> tile ids in placement order) building `structure`.

    Tiles of the structure that no robot places count as never placed. Raises ValueError for a
    tile id that is not in the structure or appears more than once.
    """
    graph = graph if graph is not None else build_graph(structure, time_model)
    index = graph.index_of
    names = list(orders)
    indexed: list[list[int]] = []
    for name in names:
        unknown = [t for t in orders[name] if t not in index]
        if unknown:
            raise ValueError(f"{name}: tile {unknown[0]} is not a tile of the structure")
        indexed.append([index[t] for t in orders[name]])
    return team_schedule(graph, names, indexed, simulate_orders(graph, indexed))
