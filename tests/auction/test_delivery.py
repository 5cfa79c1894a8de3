"""Awards and announcements repeated until answered, harmless when repeated."""

from __future__ import annotations

from auction_node.auction import Award
from auction_node.delivery import AnnouncementRepeater, AwardDelivery


def award(auction_id: int, tile_id: int, winner: str) -> Award:
    return Award(auction_id, tile_id, winner, 10.0, (winner,), (10.0,), f"{winner} wins")


def test_an_award_is_sent_again_until_its_acceptance_arrives() -> None:
    delivery = AwardDelivery(resend_period=0.25, give_up_after=10.0)
    delivery.sent(award(1, 7, "robot1"), reason=0, detected_wall=0.0, now=0.0)
    assert delivery.due_again(0.1) == []
    assert [p.award.tile_id for p in delivery.due_again(0.3)] == [7]
    assert delivery.due_again(0.4) == []  # the period counts from the last copy
    assert [p.resends for p in delivery.due_again(0.6)] == [2]
    assert delivery.accepted(1) is not None
    assert delivery.accepted(1) is None  # a second acceptance (a copy) closes nothing
    assert delivery.due_again(5.0) == [] and delivery.resends == 2


def test_a_heartbeat_listing_the_tile_accepts_the_award_whose_acceptance_was_lost() -> None:
    delivery = AwardDelivery(resend_period=0.25, give_up_after=10.0)
    delivery.sent(award(1, 7, "robot1"), 0, 0.0, 0.0)
    delivery.sent(award(2, 8, "robot2"), 0, 0.0, 0.0)
    assert delivery.taken_up("robot2", [7, 3]) == []  # robot2 did not win tile 7
    assert [p.award.auction_id for p in delivery.taken_up("robot1", [0, 7, 3])] == [1]
    assert list(delivery.pending) == [2]


def test_an_award_goes_back_to_auction_only_when_its_winner_is_lost_or_silent_too_long() -> None:
    delivery = AwardDelivery(resend_period=0.25, give_up_after=10.0)
    delivery.sent(award(1, 7, "robot1"), 0, 0.0, 0.0)
    delivery.sent(award(2, 8, "robot2"), 0, 0.0, 0.0)
    assert delivery.overdue(9.0) == []
    assert [p.award.tile_id for p in delivery.winner_lost("robot2")] == [8]
    assert [p.award.tile_id for p in delivery.overdue(10.5)] == [7]
    assert delivery.pending == {}


def test_an_announcement_is_repeated_while_some_invited_robot_has_not_bid() -> None:
    repeater = AnnouncementRepeater(resend_period=0.25)
    repeater.sent(1, 0.0)
    repeater.sent(2, 0.0)
    assert repeater.due_again(0.3, {1: True, 2: False}) == [1]  # every robot bid in auction 2
    assert repeater.due_again(0.4, {1: True, 2: False}) == []
    assert repeater.due_again(0.6, {2: False}) == []  # auction 1 closed
    assert list(repeater.last_sent) == [2] and repeater.resends == 1
