"""Auction bookkeeping: deadlines, left-out robots, lowest bid, deterministic ties."""

from __future__ import annotations

import math

from auction_node.auction import AuctionBook, choose_winner, natural_key
from auction_node.auction_node import how_it_lies
from tiling_assembly_msgs.msg import TileState


def test_lowest_bid_wins_and_ties_break_by_natural_name() -> None:
    assert choose_winner({"robot2": 50.0, "robot1": 40.0}) == "robot1"
    assert choose_winner({"robot10": 40.0, "robot2": 40.0}) == "robot2"
    assert choose_winner({"b": -1.0, "a": -1.0, "c": -5.0}) == "c"
    assert choose_winner({}) is None
    assert sorted(["robot10", "robot2", "robot1"], key=natural_key) == ["robot1", "robot2", "robot10"]


def test_auction_closes_when_everybody_bid() -> None:
    book = AuctionBook(bid_window=2.0)
    auction = book.open(5, 0, now=10.0, invited=["robot1", "robot2"])
    assert auction is not None and auction.deadline == 12.0
    assert book.open(5, 0, now=10.5, invited=["robot1"]) is None  # one auction per tile
    assert book.bid(auction.auction_id, "robot2", 30.0, now=10.1) is None
    assert book.close_ready(10.2) == []
    assert book.bid(auction.auction_id, "robot1", 30.0, now=10.3) is None
    (award,) = book.close_ready(10.3)
    assert award.winner == "robot1" and award.bidders == ("robot1", "robot2")
    assert "tie with robot2" in award.decision
    assert book.open_auctions == {}


def test_silent_robot_is_left_out_at_the_deadline() -> None:
    book = AuctionBook(bid_window=1.0)
    auction = book.open(7, 0, now=0.0, invited=["robot1", "robot2", "robot3"])
    assert auction is not None
    book.bid(auction.auction_id, "robot3", 12.5, now=0.2)
    book.bid(auction.auction_id, "robot1", 20.0, now=0.3)
    assert book.close_ready(0.9) == []
    (award,) = book.close_ready(1.0)
    assert award.winner == "robot3"
    assert "no answer from robot2" in award.decision


def test_refused_bids() -> None:
    book = AuctionBook(bid_window=1.0)
    auction = book.open(7, 0, now=0.0, invited=["robot1"])
    assert auction is not None
    assert "not open" in book.bid(99, "robot1", 1.0, 0.1)
    assert "not invited" in book.bid(auction.auction_id, "robot9", 1.0, 0.1)
    assert "not a number" in book.bid(auction.auction_id, "robot1", math.nan, 0.1)
    assert "after the deadline" in book.bid(auction.auction_id, "robot1", 1.0, 1.5)
    assert book.bid(auction.auction_id, "robot1", 1.0, 0.5) is None
    assert "already bid" in book.bid(auction.auction_id, "robot1", 0.5, 0.6)


def test_nobody_bids() -> None:
    book = AuctionBook(bid_window=1.0)
    book.open(3, 0, now=0.0, invited=["robot1"])
    (award,) = book.close_ready(1.0)
    assert award.winner == "" and "no bids" in award.decision


def test_lost_bidder_does_not_hold_up_the_auction() -> None:
    book = AuctionBook(bid_window=10.0)
    auction = book.open(3, 0, now=0.0, invited=["robot1", "robot2"])
    assert auction is not None
    book.bid(auction.auction_id, "robot1", 5.0, 0.1)
    book.forget_bidder("robot2")
    (award,) = book.close_ready(0.2)
    assert award.winner == "robot1"


def test_a_repair_line_says_how_the_tile_lies() -> None:
    """A tile of another type in its place is named, not reported 'off by 0.0 cm, +0 deg'."""
    assert how_it_lies(TileState(tile_id=10, state=TileState.MISPLACED, seen_type="triangle")) == \
        "a triangle in its place"
    shifted = TileState(tile_id=6, state=TileState.MISPLACED, offset_x=0.03, offset_y=0.04, offset_yaw=0.26)
    assert how_it_lies(shifted) == "off by 5.0 cm, +15 deg"


def test_the_book_knows_who_holds_a_tile_until_it_is_settled_and_withdraws_open_auctions() -> None:
    book = AuctionBook(bid_window=2.0)
    first = book.open(5, 0, now=0.0, invited=["robot1", "robot2"])
    assert first is not None
    book.bid(first.auction_id, "robot2", 1.0, now=0.5)
    book.close_ready(3.0)
    assert book.held_by == {5: "robot2"}
    again = book.open(7, 0, now=3.0, invited=["robot1"])
    assert again is not None
    assert book.withdraw(7) is again and book.open_auctions == {}
    assert book.withdraw(7) is None
    assert book.close_ready(10.0) == [] and 7 not in book.held_by  # withdrawn: never awarded
    book.settled(5)
    assert book.held_by == {}
