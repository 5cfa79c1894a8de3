"""Room to stand (tiling_sim.standing_room), without ROS: a base never stands on another's."""

from __future__ import annotations

import math

from tiling_sim.robot_motion import MotionModel, approach_point
from tiling_sim.standing_room import StandingRoom, alternative_spot, robot_boxes

BASE = MotionModel(base_size=(0.33, 0.33), base_clearance=0.03, approach_distance=0.25)
HALF = ((0.33 + 0.05) / 2, (0.33 + 0.05) / 2)  # a base plus half of a 5 cm clearance


def test_a_spot_another_robot_holds_is_refused_until_it_has_gone_and_the_wait_is_recorded() -> None:
    room = StandingRoom(HALF, {"robot1": (0.0, 0.0), "robot2": (2.0, 0.0), "vi": (0.0, 2.0)})
    assert room.ask("robot2", (0.3, 0.1), now=10.0) == (["robot1"], None)  # 0.3 m apart: the bases touch
    assert room.ask("robot2", (0.0, 1.7), now=11.0)[0] == ["vi"]  # a VI robot's stop is a claim too
    assert room.claims["robot2"] == (2.0, 0.0)  # refused: it still stands where it stood
    room.ask("robot1", (-1.0, 0.0), now=14.0)  # robot1 drives off: its claim goes with it
    blocking, wait = room.ask("robot2", (0.3, 0.1), now=15.0)
    assert blocking == [] and room.claims["robot2"] == (0.3, 0.1)
    assert wait is not None
    assert (wait.since, wait.seconds, wait.in_the_way, wait.forced, wait.elsewhere) == (10.0, 5.0, ("robot1",), False,
                                                                                         False)
    room.ask("robot1", (0.3, 0.3), now=20.0)
    _, beside = room.ask("robot1", (-0.3, 0.3), now=20.0)  # another spot at once: it stopped elsewhere
    assert beside is not None and beside.seconds == 0.0 and beside.elsewhere
    assert room.ask("robot2", (0.3, 0.2), now=16.0) == ([], None)  # moving on its own spot: no wait


def test_robots_asking_at_the_same_time_are_answered_in_the_teams_order() -> None:
    """Two robots setting off together: the one later in the team waits while one before it is still
    deciding what it does at that time and has not asked, whatever order their requests came in."""
    team = ["robot1", "robot2", "robot3"]
    room = StandingRoom(HALF, {"robot1": (0.0, 0.0), "robot2": (2.0, 0.0), "robot3": (4.0, 0.0)})
    assert room.ahead("robot2", 157.05, team, deciding=["robot1", "robot2"]) == ["robot1"]
    assert room.ahead("robot1", 157.05, team, deciding=["robot1", "robot2"]) == []
    room.ask("robot1", (1.0, 1.0), now=157.05)
    assert room.ahead("robot2", 157.05, team, deciding=["robot1", "robot2"]) == []  # it asked
    assert room.ahead("robot3", 160.0, team, deciding=["robot1", "robot2", "robot3"]) == ["robot1", "robot2"]
    assert room.ahead("robot3", 160.0, team, deciding=["robot3"]) == []  # the others went on
    assert room.ahead("vi", 160.0, team, deciding=team) == []  # not one of the team's bodies


def test_a_robot_that_insists_stands_there_anyway_and_the_crowding_is_recorded() -> None:
    room = StandingRoom(HALF, {"robot1": (0.0, 0.0), "robot2": (2.0, 0.0)})
    room.ask("robot2", (0.2, 0.0), now=0.0)
    blocking, wait = room.ask("robot2", (0.2, 0.0), now=60.0, insist=True)
    assert blocking == [] and wait is not None and wait.forced and wait.seconds == 60.0 and not wait.elsewhere
    assert room.claims["robot2"] == (0.2, 0.0)


def test_spots_just_clear_of_each_other_are_both_granted() -> None:
    room = StandingRoom(HALF, {"robot1": (0.0, 0.0)})
    assert room.ask("robot2", (0.39, 0.0), now=0.0) == ([], None)  # 6 cm between the bases
    assert room.in_the_way("robot3", (0.37, 0.2)) == ["robot1", "robot2"]


def test_another_stop_is_found_round_a_tile_within_reach_but_not_at_a_taken_cache() -> None:
    cache = (1.0, -0.5)  # a base standing on it leaves no stop within the arm's reach of it
    assert alternative_spot(BASE, cache, (0.0, 0.0), cache, robots=[cache], clearance=0.05) is None
    tile = (0.0, 0.0)
    preferred = (0.25, 0.0)
    beside = alternative_spot(BASE, tile, (1.0, 0.0), preferred, robots=[preferred], clearance=0.05)
    assert beside is not None and math.dist(beside, tile) <= 0.25 + 0.1 + 1e-9
    assert max(abs(beside[0] - 0.25), abs(beside[1])) >= 0.38 - 1e-9


def test_three_robots_pick_from_one_cache_at_once_and_a_fourth_waits() -> None:
    """Bases stop an arm's reach short of the cache (robot_motion.placement_phases): the second and
    third stop round it, clear of the others; with three there, a fourth finds no stop in reach."""
    cache, structure = (1.2, -0.8), (0.0, 0.0)  # pyramid_91's slab cache: every robot comes from the structure
    taken = [approach_point(BASE, cache, structure)]
    assert math.dist(taken[0], cache) == 0.25
    for _ in range(2):
        spot = alternative_spot(BASE, cache, structure, taken[0], robots=taken, clearance=0.05)
        assert spot is not None and math.dist(spot, cache) <= 0.25 + 0.1 + 1e-9
        assert all(max(abs(spot[0] - x), abs(spot[1] - y)) >= 0.38 - 1e-9 for x, y in taken)
        taken.append(spot)
    assert alternative_spot(BASE, cache, structure, taken[0], robots=taken, clearance=0.05) is None


def test_no_stop_within_reach_means_waiting() -> None:
    tile = (0.0, 0.0)
    ring = [(0.25 * math.cos(a), 0.25 * math.sin(a)) for a in [k * math.pi / 4 for k in range(8)]]
    assert alternative_spot(BASE, tile, (1.0, 0.0), ring[0], robots=ring, clearance=0.05) is None


def test_robot_boxes_are_counter_clockwise_squares() -> None:
    (box,) = robot_boxes([(1.0, 2.0)], (0.5, 0.25))
    assert box.tolist() == [[0.5, 1.75], [1.5, 1.75], [1.5, 2.25], [0.5, 2.25]]
