"""The planner: paper section 2.1 end to end, plus our improvement step and a simple baseline.

Methods:

* `paper`: the method of section 2.1 (after its reference [11]): multi-source Dijkstra from
  exterior seeds (`initial_allocation`), node trading (`node_trading`), and orders that maximise
  the time between a support's placement and the placement of the tile it carries (`sequencing`).
* `default`: layer-balanced regions (`layer_partition`) as well as the paper's, traded, then
  list scheduling with critical-path priority in which a robot that would wait may help another,
  and local search over trades and orders with the team simulation as the objective
  (`schedule_improvement`), for a makespan near the lower bound.
* `round-robin`: what a user might write instead: tiles layer by layer, dealt to the robots in
  turn, each robot placing its tiles in that order. For comparison only.

Every plan is evaluated by the team simulation (`schedule_sim`) and reported against the lower
bound (`makespan_bound`). `replan_assembly` plans the tiles not yet placed for the robots left.
"""

from __future__ import annotations

import re
import time
from collections.abc import Iterable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from enum import Enum

import numpy as np
from numpy.typing import NDArray

from planner_node.assembly_graph import AssemblyGraph, build_graph
from planner_node.initial_allocation import InitialAllocation, initial_allocation
from planner_node.layer_partition import layer_partition
from planner_node.makespan_bound import MakespanBound, makespan_lower_bound
from planner_node.node_trading import TradingResult, centroid_affinity, imbalance, trade_nodes, workloads
from planner_node.schedule_improvement import GOOD_ENOUGH, improve_plan
from planner_node.schedule_sim import SimulationResult, TeamSchedule, simulate_orders, team_schedule
from planner_node.sequencing import Policy, sequence_tiles
from tiling_assembly.structure import Structure
from tiling_assembly.time_model import TimeModel

DEFAULT_IMPROVE_TIME_LIMIT = 1.0  # s of local search in the default method
PAPER_START_LIMIT = 2000  # tiles up to which the default method also tries the paper's partition and policy
ROBOT_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")

IntArray = NDArray[np.int64]


class Method(Enum):
    DEFAULT = "default"
    PAPER = "paper"
    ROUND_ROBIN = "round-robin"


class PlanningError(ValueError):
    """A planning request that cannot be served; the message is one line saying why."""


@dataclass(frozen=True)
class RobotTask:
    """One robot's share: its tiles in placement order and its simulated times (s)."""

    robot_name: str
    tile_ids: tuple[int, ...]
    workload: float
    estimated_finish: float
    wait: float


@dataclass(frozen=True)
class PlanStats:
    """How the plan was made: stage times (s), trades, and the workload imbalance (max/mean)."""

    seconds: Mapping[str, float] = field(default_factory=dict)
    trades: int = 0
    improvement_moves: int = 0
    helped: int = 0  # tiles a robot placed for a neighbour (default method)
    partition: str = ""  # the starting partition: "dijkstra" (the paper's) or "layers"
    imbalance_initial: float = 1.0
    imbalance_traded: float = 1.0
    imbalance_final: float = 1.0
    policy: str = ""


@dataclass(frozen=True, eq=False)
class Plan:
    """A plan for a structure: every robot's task, the support relation, makespan and bound."""

    structure_name: str
    method: Method
    tasks: tuple[RobotTask, ...]
    supports: Mapping[int, tuple[int, ...]]
    makespan: float
    bound: MakespanBound
    schedule: TeamSchedule
    stats: PlanStats

    @property
    def lower_bound(self) -> float:
        return self.bound.value

    @property
    def ratio(self) -> float:
        """makespan / lower bound (1.0 when there is nothing to build)."""
        return self.makespan / self.lower_bound if self.lower_bound > 0 else 1.0

    @property
    def imbalance(self) -> float:
        return imbalance([t.workload for t in self.tasks])

    @property
    def total_wait(self) -> float:
        return sum(t.wait for t in self.tasks)

    def orders(self) -> dict[str, list[int]]:
        return {t.robot_name: list(t.tile_ids) for t in self.tasks}


def default_robot_names(count: int) -> list[str]:
    return [f"robot{k}" for k in range(1, count + 1)]


def check_robot_names(names: Sequence[str]) -> None:
    """Raise PlanningError unless the names are distinct, non-empty ROS names."""
    if not names:
        raise PlanningError("no robots to plan for")
    for name in names:
        if not ROBOT_NAME.match(name):
            raise PlanningError(f"robot name {name!r} is not a valid ROS name (letters, digits, _)")
    if len(set(names)) != len(names):
        raise PlanningError(f"robot names must be distinct, got {', '.join(names)}")


def round_robin_orders(graph: AssemblyGraph, n_robots: int) -> list[list[int]]:
    """The baseline: tiles by layer (then x, y), dealt to the robots in turn."""
    order = np.lexsort((graph.tile_ids, graph.centroids[:, 1], graph.centroids[:, 0], graph.layer))
    return [order[r::n_robots].tolist() for r in range(n_robots)]


def _package(
    structure: Structure,
    graph: AssemblyGraph,
    names: Sequence[str],
    orders: list[list[int]],
    result: SimulationResult,
    method: Method,
    bound: MakespanBound,
    stats: PlanStats,
) -> Plan:
    if not result.completed:  # the sequencing guarantees this; a failure here is a bug
        raise RuntimeError(f"the plan deadlocks at tiles {sorted(graph.tile_ids[list(result.blocked)])}")
    tasks = tuple(
        RobotTask(
            robot_name=name,
            tile_ids=tuple(int(graph.tile_ids[t]) for t in order),
            workload=float(graph.cost[order].sum()) if order else 0.0,
            estimated_finish=float(result.robot_finish[r]),
            wait=float(result.robot_wait[r]),
        )
        for r, (name, order) in enumerate(zip(names, orders, strict=True))
    )
    return Plan(
        structure_name=structure.name,
        method=method,
        tasks=tasks,
        supports={t: tuple(structure.supports[t]) for t in structure.tiles},
        makespan=result.makespan,
        bound=bound,
        schedule=team_schedule(graph, names, orders, result),
        stats=stats,
    )


class _Stopwatch:
    """Seconds spent in each planning stage, and in total since the stopwatch was made."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = {}
        self.started = time.perf_counter()

    @contextmanager
    def stage(self, name: str) -> Iterator[None]:
        tic = time.perf_counter()
        yield
        self.seconds[name] = time.perf_counter() - tic

    def stop(self) -> dict[str, float]:
        self.seconds["total"] = time.perf_counter() - self.started
        return self.seconds


@dataclass(frozen=True, eq=False)
class _Sequenced:
    """What every method produces: the orders, their simulation, and how they were made."""

    orders: list[list[int]]
    result: SimulationResult
    stats: PlanStats  # without the stage times, which plan_assembly adds at the end


def plan_assembly(
    structure: Structure,
    robot_names: Sequence[str],
    time_model: TimeModel,
    method: Method = Method.DEFAULT,
    improve_time_limit: float = DEFAULT_IMPROVE_TIME_LIMIT,
    help_neighbours: bool = True,
    robot_starts: Sequence[tuple[float, float]] = (),
) -> Plan:
    """Split `structure` among the robots and order each robot's tiles (see the module docstring).

    `help_neighbours` (default method): let a robot that would wait place ready tiles of another
    robot when that finishes the build sooner; without it every robot keeps to its own connected
    region. `robot_starts` (x, y in the structure's frame per robot, m): where the robots stand at
    the start; the tasks are made as if every robot started at its first tile's cache, then handed
    to the robots nearest those caches, and the plan's times count each robot's drive there.
    """
    check_robot_names(robot_names)
    n_robots = len(robot_names)
    if robot_starts and len(robot_starts) != n_robots:
        raise PlanningError(f"{len(robot_starts)} start positions for {n_robots} robots")
    time_model = time_model.for_team(structure, n_robots)  # robots crowding the caches cost time
    stopwatch = _Stopwatch()
    with stopwatch.stage("graph"):
        graph = build_graph(structure, time_model)
        bound = makespan_lower_bound(graph, n_robots)
    if len(graph) == 0:
        sequenced = _nothing_to_place(graph, n_robots=n_robots)
    elif method is Method.ROUND_ROBIN:
        sequenced = _round_robin_plan(graph, n_robots=n_robots, stopwatch=stopwatch)
    else:
        with stopwatch.stage("allocation"):
            allocation = initial_allocation(graph, n_robots)
        if method is Method.PAPER:
            sequenced = _paper_plan(graph, allocation=allocation, n_robots=n_robots, stopwatch=stopwatch)
        else:
            sequenced = _improved_plan(
                graph, allocation=allocation, n_robots=n_robots, good_enough=GOOD_ENOUGH * bound.strongest,
                improve_time_limit=improve_time_limit, help_neighbours=help_neighbours, stopwatch=stopwatch,
            )
    if robot_starts:
        with stopwatch.stage("starts"):
            graph = replace(graph, first_trip=time_model.start_trips(structure, robot_starts))
            sequenced = _handed_to_the_nearest(graph, sequenced)
    stats = replace(sequenced.stats, seconds=stopwatch.stop())
    return _package(structure, graph, robot_names, sequenced.orders, sequenced.result, method, bound, stats)


def _handed_to_the_nearest(graph: AssemblyGraph, sequenced: _Sequenced) -> _Sequenced:
    """The tasks handed to the robots so that the last to finish, its drive to its first tile's
    cache counted (`graph.first_trip`), finishes soonest, then the drives are shortest in all;
    simulated with those drives.

    Only who takes which task changes: planned with the drives, the orders start every robot at the
    cache nearest to it, which is often the same cache for all, and nothing charges robots for
    meeting there (paper_14: both robots placed the bottom row in lockstep, 10% over plan)."""
    from scipy.optimize import linear_sum_assignment

    orders = sequenced.orders
    drives = np.array([[trips[order[0]] if order else 0.0 for order in orders] for trips in graph.first_trip])
    finish = drives + sequenced.result.robot_finish[None, :]
    limits = np.unique(finish)
    low, high = 0, len(limits) - 1  # the least limit on finish times that every robot can keep
    while low < high:
        middle = (low + high) // 2
        over = (finish > limits[middle]).astype(float)
        robots, tasks = linear_sum_assignment(over)
        low, high = (low, middle) if over[robots, tasks].sum() == 0 else (middle + 1, high)
    robots, tasks = linear_sum_assignment(drives + (finish > limits[low]) * (1.0 + drives.sum()))
    handed = [orders[k] for _, k in sorted(zip(robots.tolist(), tasks.tolist(), strict=True))]
    return _Sequenced(handed, simulate_orders(graph, handed), sequenced.stats)


def _nothing_to_place(graph: AssemblyGraph, *, n_robots: int) -> _Sequenced:
    """Everything is placed already: every robot gets an empty task."""
    orders: list[list[int]] = [[] for _ in range(n_robots)]
    return _Sequenced(orders, simulate_orders(graph, orders), PlanStats())


def _round_robin_plan(graph: AssemblyGraph, *, n_robots: int, stopwatch: _Stopwatch) -> _Sequenced:
    """The baseline; its deal is final, so all three imbalances are the same."""
    with stopwatch.stage("sequencing"):
        orders = round_robin_orders(graph, n_robots)
        result = simulate_orders(graph, orders)
    balance = imbalance([float(graph.cost[o].sum()) for o in orders])
    stats = PlanStats(
        imbalance_initial=balance, imbalance_traded=balance, imbalance_final=balance, policy="layer order"
    )
    return _Sequenced(orders, result, stats)


def _paper_plan(
    graph: AssemblyGraph, *, allocation: InitialAllocation, n_robots: int, stopwatch: _Stopwatch
) -> _Sequenced:
    """Section 2.1 as published: the Dijkstra regions, node trading, maximum-slack orders."""
    with stopwatch.stage("trading"):
        traded = trade_nodes(graph, allocation.owner, n_robots, allocation.seed_distance)
    with stopwatch.stage("sequencing"):
        orders = sequence_tiles(graph, traded.owner, n_robots, Policy.MAX_SLACK, allocation.distance).orders
        result = simulate_orders(graph, orders)
    stats = _partition_stats(
        graph,
        trading={"dijkstra": traded},
        start="dijkstra",
        owner=traded.owner,
        n_robots=n_robots,
        policy=Policy.MAX_SLACK.value,
        moves=0,
        helped=0,
    )
    return _Sequenced(orders, result, stats)


def _improved_plan(
    graph: AssemblyGraph,
    *,
    allocation: InitialAllocation,
    n_robots: int,
    good_enough: float,
    improve_time_limit: float,
    help_neighbours: bool,
    stopwatch: _Stopwatch,
) -> _Sequenced:
    """The default method: the best of several traded partitions, then local search."""
    with stopwatch.stage("partitions"):
        trading, starts = _start_partitions(graph, allocation=allocation, n_robots=n_robots)
    with stopwatch.stage("improvement"):
        improved = improve_plan(
            graph,
            starts,
            n_robots,
            allocation.distance,
            improve_time_limit,
            good_enough=good_enough,
            help_neighbours=help_neighbours,
            max_slack=len(graph) <= PAPER_START_LIMIT,
        )
    stats = _partition_stats(
        graph,
        trading=trading,
        start=improved.start,
        owner=improved.owner,
        n_robots=n_robots,
        policy=improved.policy,
        moves=improved.moves,
        helped=improved.helped,
    )
    return _Sequenced(improved.orders, improved.result, stats)


def _start_partitions(
    graph: AssemblyGraph, *, allocation: InitialAllocation, n_robots: int
) -> tuple[dict[str, TradingResult], dict[str, IntArray]]:
    """The partitions the default method starts from, by name, and the tradings behind them.

    The order counts: among equally good plans `improve_plan` keeps the first. The paper's
    partition is left out of big structures, where trading it costs more than it gains.
    """
    sliced = layer_partition(graph, n_robots)
    trading = {"layers": trade_nodes(graph, sliced, n_robots, centroid_affinity(graph, sliced, n_robots))}
    starts = {"layers": trading["layers"].owner, "layers-untraded": sliced}
    if len(graph) <= PAPER_START_LIMIT:
        trading["dijkstra"] = trade_nodes(graph, allocation.owner, n_robots, allocation.seed_distance)
        starts["dijkstra"] = trading["dijkstra"].owner
    return trading, starts


def _partition_stats(
    graph: AssemblyGraph,
    *,
    trading: Mapping[str, TradingResult],
    start: str,
    owner: IntArray,
    n_robots: int,
    policy: str,
    moves: int,
    helped: int,
) -> PlanStats:
    """How the plan grew from its start partition (`trading` holds the tradings of the starts)."""
    chosen = trading["dijkstra" if start == "dijkstra" else "layers"]
    trades, traded_imbalance = chosen.trades, chosen.imbalance_after
    if start == "layers-untraded":  # the layer slices did best as they were, without trading
        trades, traded_imbalance = 0, chosen.imbalance_before
    return PlanStats(
        trades=trades,
        improvement_moves=moves,
        imbalance_initial=chosen.imbalance_before,
        imbalance_traded=traded_imbalance,
        imbalance_final=imbalance(workloads(graph, owner, n_robots)),
        policy=policy,
        helped=helped,
        partition=start,
    )


def replan_assembly(
    structure: Structure,
    placed_tile_ids: Iterable[int],
    robot_names: Sequence[str],
    time_model: TimeModel,
    method: Method = Method.DEFAULT,
    improve_time_limit: float = DEFAULT_IMPROVE_TIME_LIMIT,
    help_neighbours: bool = True,
) -> Plan:
    """Plan the tiles not yet placed for `robot_names`, starting now (times from 0).

    Supports already placed are met; the plan's support relation still lists them, as in the
    structure. Raises PlanningError for placed ids that are not tiles of the structure.
    """
    placed = set(int(t) for t in placed_tile_ids)
    unknown = sorted(placed - set(structure.tiles))
    if unknown:
        shown = ", ".join(str(t) for t in unknown[:5]) + (" ..." if len(unknown) > 5 else "")
        raise PlanningError(f"placed tile ids not in structure '{structure.name}': {shown}")
    check_robot_names(robot_names)
    remaining = structure.subset(t for t in structure.tiles if t not in placed)
    plan = plan_assembly(remaining, robot_names, time_model, method, improve_time_limit, help_neighbours)
    return replace(plan, supports={t: tuple(structure.supports[t]) for t in remaining.tiles})
