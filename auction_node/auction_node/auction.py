"""Auctioning a tile to the team (paper section 2.3).

"Once the error has been detected, the scanning robot sends a message to inform the assembly
robots that the block is missing and asks for bids to determine which robot will replace the
missing block." One auction per tile: it is announced to the robots alive at that moment with a
deadline; it closes as soon as every invited robot has bid, or at the deadline, and the lowest
bid wins. Robots that do not answer in time are left out; ties go to the robot whose name sorts
first in natural order (robot2 before robot10), so every run decides alike. An auction nobody bid
in is reopened later by the caller.

Beyond the paper: the book remembers who won each tile (`held_by`) until the caller says the tile is
settled (placed, or given up). A tile found lying wrong while its re-placement is auctioned, or held
by a robot, must not become a second task for another robot: the caller withdraws the open auction
and gives the repair to the robot that holds the tile (two robots would carry it to one place).
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from dataclasses import dataclass, field


def natural_key(name: str) -> tuple[object, ...]:
    """Sort key that orders embedded numbers by value: robot2 < robot10."""
    return tuple(int(part) if part.isdigit() else part for part in re.split(r"(\d+)", name))


@dataclass
class Auction:
    auction_id: int
    tile_id: int
    reason: int
    opened_at: float  # s, the caller's clock
    deadline: float  # s
    invited: frozenset[str]
    bids: dict[str, float] = field(default_factory=dict)

    def complete(self, now: float) -> bool:
        return self.invited <= set(self.bids) or now >= self.deadline


@dataclass(frozen=True)
class Award:
    auction_id: int
    tile_id: int
    winner: str  # "" when nobody bid
    winning_bid: float
    bidders: tuple[str, ...]  # lowest bid first
    bids: tuple[float, ...]
    decision: str  # one readable line


def choose_winner(bids: dict[str, float]) -> str | None:
    """The lowest bid; ties broken by natural name order."""
    if not bids:
        return None
    return min(bids, key=lambda robot: (bids[robot], natural_key(robot)))


@dataclass
class AuctionBook:
    """Open auctions and their bids."""

    bid_window: float = 1.0  # s from announcement to deadline
    next_id: int = 1
    open_auctions: dict[int, Auction] = field(default_factory=dict)
    held_by: dict[int, str] = field(default_factory=dict)  # tile -> winner of its latest award, until settled

    def open(self, tile_id: int, reason: int, now: float, invited: Iterable[str]) -> Auction | None:
        """Announce `tile_id`; None when it is already being auctioned."""
        if any(a.tile_id == tile_id for a in self.open_auctions.values()):
            return None
        auction = Auction(self.next_id, tile_id, reason, now, now + self.bid_window, frozenset(invited))
        self.open_auctions[auction.auction_id] = auction
        self.next_id += 1
        return auction

    def withdraw(self, tile_id: int) -> Auction | None:
        """Close the open auction of `tile_id` without an award (what it was for is moot); the auction
        withdrawn, or None when none was open."""
        auction = next((a for a in self.open_auctions.values() if a.tile_id == tile_id), None)
        if auction is not None:
            del self.open_auctions[auction.auction_id]
        return auction

    def settled(self, tile_id: int) -> None:
        """`tile_id` was placed, or given up by its holder: nobody holds it any more."""
        self.held_by.pop(tile_id, None)

    def bid(self, auction_id: int, robot: str, value: float, now: float) -> str | None:
        """Record a bid; returns why it was refused, or None when taken."""
        auction = self.open_auctions.get(auction_id)
        if auction is None:
            return f"auction {auction_id} is not open"
        if robot not in auction.invited:
            return f"{robot} was not invited to auction {auction_id}"
        if now > auction.deadline:
            return f"{robot}'s bid for auction {auction_id} came after the deadline"
        if robot in auction.bids:
            return f"{robot} already bid in auction {auction_id}"
        if value != value:  # NaN
            return f"{robot}'s bid for auction {auction_id} is not a number"
        auction.bids[robot] = value
        return None

    def forget_bidder(self, robot: str) -> None:
        """A robot was lost: stop waiting for its bids."""
        for auction in self.open_auctions.values():
            if robot in auction.invited and robot not in auction.bids:
                auction.invited = auction.invited - {robot}

    def close_ready(self, now: float) -> list[Award]:
        """Decide every auction that is complete."""
        awards = []
        for auction_id in sorted(self.open_auctions):
            auction = self.open_auctions[auction_id]
            if not auction.complete(now):
                continue
            del self.open_auctions[auction_id]
            award = decide(auction)
            if award.winner:
                self.held_by[award.tile_id] = award.winner
            awards.append(award)
        return awards


def decide(auction: Auction) -> Award:
    """The award of a closed auction, with a one-line explanation."""
    ranked = sorted(auction.bids, key=lambda r: (auction.bids[r], natural_key(r)))
    silent = sorted(auction.invited - set(auction.bids), key=natural_key)
    winner = choose_winner(auction.bids)
    bids_text = ", ".join(f"{r} {auction.bids[r]:.1f}" for r in ranked) or "none"
    silent_text = f"; no answer from {', '.join(silent)}" if silent else ""
    if winner is None:
        decision = f"auction {auction.auction_id} for tile {auction.tile_id}: no bids{silent_text}; reopening later"
        return Award(auction.auction_id, auction.tile_id, "", float("nan"), (), (), decision)
    tie = [r for r in ranked if auction.bids[r] == auction.bids[winner]]
    tie_text = f" (tie with {', '.join(r for r in tie if r != winner)}, broken by name)" if len(tie) > 1 else ""
    decision = (
        f"auction {auction.auction_id} for tile {auction.tile_id}: {winner} wins with "
        f"{auction.bids[winner]:.1f}{tie_text}; bids: {bids_text}{silent_text}"
    )
    return Award(
        auction.auction_id,
        auction.tile_id,
        winner,
        auction.bids[winner],
        tuple(ranked),
        tuple(auction.bids[r] for r in ranked),
        decision,
    )
