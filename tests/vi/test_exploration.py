"""Prioritized exploration of the VI robot (vi_node.exploration), without ROS."""

from __future__ import annotations

import math

import pytest

from tiling_assembly.structure_file import load_structure
from vi_node.exploration import MISSING, OCCLUDED, PRESENT, Exploration, PriorityWeights, nearest, ring_viewpoints

WEIGHTS = PriorityWeights(just_placed=4.0, undetermined=2.0, suspected=5.0, stale_time=60.0)


def _explored() -> Exploration:
    exploration = Exploration(WEIGHTS)
    exploration.expect([1, 2, 3, 4])
    exploration.judged({1: PRESENT, 2: PRESENT, 3: OCCLUDED, 4: MISSING}, now=100.0)
    return exploration


def test_priority_follows_what_is_known_of_each_tile() -> None:
    exploration = _explored()
    exploration.placed(2, now=110.0)
    priority = exploration.priority(now=130.0)
    assert priority[1] == pytest.approx(30.0 / 60.0)  # seen present 30 s ago: grows back to 1
    assert priority[2] == 4.0  # placed again since it was judged
    assert priority[3] == 2.0 and priority[4] == 2.0  # undetermined, a missing call to confirm
    assert exploration.priority(now=1000.0)[1] == 1.0
    assert exploration.unresolved() == [2, 3, 4]


def test_a_tile_a_robot_found_absent_is_looked_at_first_until_a_scan_judges_it() -> None:
    exploration = _explored()
    exploration.suspected(1, now=120.0)
    exploration.suspected(99, now=120.0)  # not expected: ignored
    priority = exploration.priority(now=121.0)
    assert max(priority, key=priority.get) == 1 and priority[1] == 5.0
    assert 99 not in priority
    assert 1 in exploration.unresolved()
    exploration.judged({2: PRESENT}, now=125.0)  # a scan that did not see tile 1
    assert exploration.priority(now=126.0)[1] == 5.0
    exploration.judged({1: MISSING}, now=130.0)
    assert exploration.priority(now=131.0)[1] == 2.0  # now a missing call to confirm


def test_a_choice_made_as_of_a_scan_knows_only_what_had_happened_by_then() -> None:
    """News stamped after the scan a choice is made on (a placement, an absence, heard while the scan
    was judged: more of it on a busy host) has not happened yet for that choice; a tile S_a did not
    hold then counts for nothing."""
    exploration = _explored()
    exploration.placed(1, now=140.0)
    exploration.suspected(2, now=145.0)
    exploration.expect([1, 2, 3, 4, 5])
    exploration.placed(5, now=150.0)
    then = exploration.priority(now=130.0, among=[1, 2, 3, 4])
    assert then[1] == pytest.approx(30.0 / 60.0) and then[2] == pytest.approx(30.0 / 60.0) and 5 not in then
    assert exploration.unresolved(130.0, among=[1, 2, 3, 4]) == [3, 4]
    later = exploration.priority(now=150.0)
    assert later[1] == 4.0 and later[2] == 5.0 and later[5] == 4.0
    assert exploration.unresolved() == [1, 2, 3, 4, 5]
    assert exploration.priority(now=130.0, among=[6])[6] == 2.0  # expected then, never judged: undetermined


def test_supports_of_the_next_placements_are_looked_at_again_once_their_last_look_is_old() -> None:
    """The currently targeted building region: a support seen present long ago is worth a look
    before a robot places on it (a tile removed meanwhile stops that robot); one seen a moment ago
    is not; the others grow back as before."""
    weights = PriorityWeights(next_support=3.0, support_recheck=20.0, stale_time=60.0)
    exploration = Exploration(weights)
    exploration.expect([1, 2, 3])
    exploration.judged({1: PRESENT, 2: PRESENT, 3: PRESENT}, now=100.0)
    exploration.targeted([1, 2])
    exploration.judged({2: PRESENT}, now=125.0)
    priority = exploration.priority(now=130.0)
    assert priority[1] == pytest.approx(3.0)  # 30 s since its last look: the full weight
    assert priority[2] == pytest.approx(3.0 * 5.0 / 20.0)  # seen 5 s ago
    assert priority[3] == pytest.approx(30.0 / 60.0)  # no placement rests on it
    exploration.targeted([])
    assert exploration.priority(now=130.0)[1] == pytest.approx(30.0 / 60.0)


def test_choose_weighs_gain_against_driving_and_avoids_failed_viewpoints() -> None:
    exploration = Exploration(WEIGHTS, travel_cost=1.0, failure_memory=30.0)
    candidates = [(0.0, 0.0, 0.0), (2.0, 0.0, 0.0), (0.0, 3.0, 0.0)]
    here = (0.0, 0.0, 0.0)
    assert exploration.choose(candidates, here, 0.0, [1.5, 3.5, 3.6]) == (1, pytest.approx(1.5))
    exploration.viewpoint_failed(1, now=0.0)
    assert exploration.choose(candidates, here, 10.0, [1.5, 3.5, 3.6])[0] == 0
    assert exploration.choose(candidates, here, 31.0, [1.5, 3.5, 3.6])[0] == 1  # forgotten after 30 s
    # where it stands counts half: a missing call is confirmed from another camera position
    assert exploration.choose([here, (0.5, 0.0, 0.0)], here, 40.0, [2.0, 1.6]) == (1, pytest.approx(1.1))


def test_another_vi_robots_claim_keeps_this_one_away_from_its_place_and_its_tiles() -> None:
    exploration = Exploration(WEIGHTS, travel_cost=0.0, claim_clearance=0.5, shared_weight=0.25)
    exploration.expect([1, 2, 3])
    exploration.judged({1: OCCLUDED, 2: OCCLUDED, 3: PRESENT}, now=0.0)
    priority = exploration.priority(now=30.0, left_to_others={2, 99})
    assert priority[1] == 2.0 and priority[2] == pytest.approx(0.5)  # the other's view resolves tile 2
    assert 99 not in priority and priority[3] == pytest.approx(0.5)  # only the stale weight of a present tile
    candidates = [(0.0, 1.0, 0.0), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0)]
    here = (1.0, 0.0, 0.0)
    assert exploration.choose(candidates, here, 30.0, [5.0, 3.0, 1.0])[0] == 0
    assert exploration.choose(candidates, here, 30.0, [5.0, 3.0, 1.0], claimed=[(0.1, 1.2, 0.0)])[0] == 1
    every = [(0.0, 1.0, 0.0), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0)]
    assert exploration.choose(candidates, here, 30.0, [5.0, 3.0, 1.0], claimed=every)[0] == 0  # none left: the first
    # before any claim: a viewpoint nearer another VI robot than this one counts a quarter
    assert exploration.choose(candidates, here, 30.0, [5.0, 3.0, 1.0], neighbours=[(0.0, 1.5, 0.0)])[0] == 1


def test_ring_viewpoints_face_the_structure() -> None:
    structure = load_structure("config/structures/paper_14.yaml")
    poses = ring_viewpoints(structure, [1.0, 1.5], 6)
    assert len(poses) == 12
    lo, hi = structure.bounds
    centre = ((lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2)
    for x, y, yaw in poses:
        assert math.dist((x, y), centre) == pytest.approx(1.0) or math.dist((x, y), centre) == pytest.approx(1.5)
        bearing = math.atan2(centre[1] - y, centre[0] - x)
        assert abs(math.remainder(yaw - bearing, 2 * math.pi)) < 1e-9
    assert nearest(poses, (centre[0] + 1.0, centre[1], 0.0)) == 0


def test_a_place_whose_scan_left_a_tile_undetermined_is_not_counted_on_to_resolve_it_for_a_while() -> None:
    """An octagon placed instead of a triangle hid two tiles under it from the one place the ray
    traced S_a predicted them seen: the explorer looked from there 240 times."""
    exploration = Exploration(WEIGHTS, blind_memory=60.0, blind_radius=0.3)
    exploration.expect([3, 9, 5])
    priority = {3: 2.0, 9: 2.0, 5: 1.0}
    there, elsewhere = (-1.11, -0.46, 0.4), (1.0, 0.5, 3.5)
    assert exploration.gain(there, (3, 9, 5), priority, now=0.0) == pytest.approx(5.0)
    exploration.judged({3: OCCLUDED, 9: OCCLUDED, 5: PRESENT}, now=10.0, view=(-1.02, -0.42))  # camera ahead of base
    assert exploration.gain(there, (3, 9, 5), priority, now=11.0) == pytest.approx(1.0)
    assert exploration.gain(elsewhere, (3, 9), priority, now=11.0) == pytest.approx(4.0)
    assert exploration.gain(there, (3, 9, 5), priority, now=71.0) == pytest.approx(5.0)  # forgotten after 60 s
    exploration.judged({3: OCCLUDED}, now=80.0)  # where the camera stood unknown: nothing to avoid
    assert exploration.gain(there, (3,), priority, now=81.0) == pytest.approx(2.0)
