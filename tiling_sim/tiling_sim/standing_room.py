"""Room to stand: one robot's base cannot stand where another's stands (issue: plans that execute as
planned; the paper's robots shared one floor, and the simulation must charge what that costs).

Every robot holds the spot it stands at or is driving to: its claim, an axis-aligned box of its
base's size plus a clearance. Before an assembly robot drives to a stop (a parts cache, or its
place beside the structure) it asks the world for the spot; the world grants it when the box there
overlaps no other robot's claim, and the spot becomes the robot's claim. Refused, the body tries
another spot within reach (`alternative_spot`: round the cache, or round the tile) and otherwise
waits where it stands and asks again; after `patience` s of waiting it drives there anyway (two
robots each waiting for the other's spot would otherwise wait for ever), which the world records
as a crowding. VI robots ask nothing (their explorer keeps clear of other robots) but their
stops are claims too. The world records every wait, for the report.

Robots that ask at the same moment of simulated time (two robots setting off together once the
support they both waited for is placed) are answered in the team's order, not in the order their
requests cross the network (`ahead`): which of them got the spot used to depend on how busy the
host was, and with it the whole trial (279 s on a quiet host, 291 s under a CPU hog).
"""

from __future__ import annotations

from collections.abc import Collection, Sequence
from dataclasses import dataclass, field

import numpy as np

from tiling_sim.robot_motion import MotionModel, Point2, Polygon, approach_point, footprints_overlap


@dataclass(frozen=True)
class Wait:
    robot: str
    since: float  # s of simulated time of the first refusal
    seconds: float  # until the spot, or another, was granted
    in_the_way: tuple[str, ...]  # the robots whose claims stood in the way first
    forced: bool  # it went after `patience` s although the spot was still taken
    elsewhere: bool  # it stopped at another spot than the one first refused


@dataclass
class StandingRoom:
    half_size: Point2  # m: half the base's footprint plus half the clearance two bases keep
    claims: dict[str, Point2] = field(default_factory=dict)  # robot -> where it stands or goes
    asked_at: dict[str, float] = field(default_factory=dict)  # robot -> when it last asked (s)
    _refused: dict[str, tuple[float, tuple[str, ...], Point2]] = field(default_factory=dict)  # robot -> first refusal

    def in_the_way(self, robot: str, spot: Point2) -> list[str]:
        """The other robots whose claims the base of `robot` would overlap at `spot`."""
        x, y = spot
        hx, hy = self.half_size
        return [other for other, (ox, oy) in self.claims.items()
                if other != robot and abs(ox - x) < 2 * hx and abs(oy - y) < 2 * hy]

    def moved(self, robot: str, spot: Point2) -> None:
        """`robot` stands at, or is driving to, `spot` (a robot that asks nothing)."""
        self.claims[robot] = spot

    def ask(self, robot: str, spot: Point2, now: float, insist: bool = False) -> tuple[list[str], Wait | None]:
        """`robot` asks to stand at `spot` at `now` (s); `insist`: it has waited long enough.

        Returns the robots in the way (empty: granted, the spot is its claim now) and, when this
        grant ends a wait, that wait.
        """
        self.asked_at[robot] = now
        blocking = self.in_the_way(robot, spot)
        if blocking and not insist:
            self._refused.setdefault(robot, (now, tuple(blocking), spot))
            return blocking, None
        self.claims[robot] = spot
        refused = self._refused.pop(robot, None)
        if refused is None:
            return [], None
        since, first, wanted = refused
        return [], Wait(robot, since, now - since, first, forced=bool(blocking), elsewhere=spot != wanted)

    def ahead(self, robot: str, now: float, team: Sequence[str], deciding: Collection[str]) -> list[str]:
        """The robots before `robot` in `team` that may still ask at `now` (s): they are `deciding`
        what they do at `now` (the world's clock waits for them there) and have not asked at `now`.
        `robot` asks again once they have asked or gone on."""
        if robot not in team:
            return []
        before = team[: team.index(robot)]
        return [other for other in before if other in deciding and self.asked_at.get(other) != now]

    def others(self, robot: str) -> list[Point2]:
        return [spot for other, spot in self.claims.items() if other != robot]


def robot_boxes(spots: Sequence[Point2], half_size: Point2) -> list[Polygon]:
    """Boxes of `half_size` round `spots` (the bases standing there), as counter-clockwise polygons."""
    hx, hy = half_size
    return [np.array([[x - hx, y - hy], [x + hx, y - hy], [x + hx, y + hy], [x - hx, y + hy]]) for x, y in spots]


def alternative_spot(
    model: MotionModel, target: Point2, towards: Point2, preferred: Point2, robots: Sequence[Point2],
    clearance: float, obstacles: Sequence[Polygon] = (), reach: float = 0.1,
) -> Point2 | None:
    """Another stop from which the robot can still work at `target` (a cache, or a tile to place),
    `clearance` (m) clear of the bases standing at `robots` and clear of `obstacles`: the nearest
    stop round `target` (see `robot_motion.approach_point`, seen from `towards`) no more than
    `reach` (m) further from it than the `preferred` stop, or than the arm's approach distance;
    None when there is none."""
    # approach_point keeps the tiles' clearance from every obstacle: robots' boxes grow by the rest
    grow = max(clearance - model.base_clearance, 0.0)
    taken = robot_boxes(robots, (model.base_size[0] / 2 + grow, model.base_size[1] / 2 + grow))
    limit = max(float(np.hypot(preferred[0] - target[0], preferred[1] - target[1])), model.approach_distance) + reach
    half = (model.base_size[0] / 2 + model.base_clearance, model.base_size[1] / 2 + model.base_clearance)
    # only what a base within `limit` of the target can touch: the search's span follows its obstacles
    near = limit + float(np.hypot(*half))
    close = [p for p in [*obstacles, *taken] if float(np.min(np.hypot(*(p - np.asarray(target)).T))) <= near]
    spot = approach_point(model, target, towards, close or taken)
    blocked = any(footprints_overlap(np.array([spot]), half, box)[0] for box in taken)
    if blocked or float(np.hypot(spot[0] - target[0], spot[1] - target[1])) > limit:
        return None
    return spot
