"""A robot cut off from the auction node starts no new tile."""

from __future__ import annotations

from assembly_node.team_contact import TeamContact


def test_a_robot_that_never_heard_an_auction_node_is_not_held() -> None:
    assert TeamContact("robot1", timeout=1.5).hold_reason(100.0, adopted_revision=-1) == ""


def test_a_robot_that_stops_hearing_the_auction_node_starts_no_new_tile() -> None:
    contact = TeamContact("robot1", timeout=1.5)
    contact.heard(10.0, plan_revision=1, lost_robots=[])
    assert contact.hold_reason(11.0, adopted_revision=1) == ""
    assert "cannot hear the auction node for 2.0 s" in contact.hold_reason(12.0, adopted_revision=1)


def test_a_robot_counted_lost_waits_until_taken_back_and_until_it_has_the_new_plan() -> None:
    contact = TeamContact("robot2", timeout=1.5)
    contact.heard(10.0, plan_revision=2, lost_robots=["robot2"])
    assert "counts this robot lost" in contact.hold_reason(10.1, adopted_revision=1)
    contact.heard(10.2, plan_revision=2, lost_robots=[])
    assert contact.hold_reason(10.3, adopted_revision=1) == "waiting for plan revision 2 (have 1)"
    assert contact.hold_reason(10.3, adopted_revision=2) == ""
    contact.heard(10.4, plan_revision=1, lost_robots=["robot1"])  # an older status arriving late
    assert contact.plan_in_force == 2 and contact.hold_reason(10.5, adopted_revision=2) == ""
