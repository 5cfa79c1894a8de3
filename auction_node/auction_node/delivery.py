"""Auction messages that arrive over a lossy link (beyond the paper, whose robots shared 802.11b).

DDS repairs a lost sample of a reliable topic only at the writer's next heartbeat (seconds in
Fast DDS's defaults), and not at all for a robot whose link was down long enough for its
participant to be forgotten. The auction therefore repeats what it is waiting for, every
`resend_period` of wall-clock time, and every repetition is harmless at the receiver:

- an announcement goes out again to the invited robots that have not bid, until its deadline (a
  robot answers a repeated announcement with the bid it already made);
- an award goes out again until the winner accepts it, or the winner's heartbeat lists the tile
  in its task (its acceptance was the message that got lost). It is auctioned again only when the
  winner is lost or `give_up_after` passes without a word from it, never merely because an
  acceptance is late: two robots would then place the same tile.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field

from auction_node.auction import Award


@dataclass
class PendingAward:
    award: Award
    reason: int
    detected_wall: float  # wall time the mismatch was detected; 0 when not a detection
    first_sent: float  # s, the caller's wall clock
    last_sent: float
    resends: int = 0


@dataclass
class AwardDelivery:
    """Awards sent and not yet accepted."""

    resend_period: float  # s of wall-clock time between two copies of an award
    give_up_after: float  # s without acceptance from a winner still heard
    pending: dict[int, PendingAward] = field(default_factory=dict)  # auction id -> award
    resends: int = 0  # copies sent over all awards

    def sent(self, award: Award, reason: int, detected_wall: float, now: float) -> None:
        self.pending[award.auction_id] = PendingAward(award, reason, detected_wall, now, now)

    def accepted(self, auction_id: int) -> PendingAward | None:
        """The winner's acceptance arrived; the award it closes, or None when already closed."""
        return self.pending.pop(auction_id, None)

    def taken_up(self, robot: str, task: Iterable[int]) -> list[PendingAward]:
        """`robot`'s heartbeat lists `task`: awards of those tiles to it are accepted."""
        tiles = set(task)
        done = [p for p in self.pending.values() if p.award.winner == robot and p.award.tile_id in tiles]
        for pending in done:
            del self.pending[pending.award.auction_id]
        return done

    def due_again(self, now: float) -> list[PendingAward]:
        """Awards whose copy is due now (the caller publishes them again)."""
        due = [p for p in self.pending.values() if now - p.last_sent >= self.resend_period]
        for pending in due:
            pending.last_sent = now
            pending.resends += 1
            self.resends += 1
        return due

    def overdue(self, now: float) -> list[PendingAward]:
        """Awards nobody accepted for `give_up_after`: the caller auctions them again."""
        late = [p for p in self.pending.values() if now - p.first_sent > self.give_up_after]
        for pending in late:
            del self.pending[pending.award.auction_id]
        return late

    def winner_lost(self, robot: str) -> list[PendingAward]:
        """`robot` was declared lost: its unaccepted awards go back to auction."""
        lost = [p for p in self.pending.values() if p.award.winner == robot]
        for pending in lost:
            del self.pending[pending.award.auction_id]
        return lost


@dataclass
class AnnouncementRepeater:
    """When each open auction's announcement last went out."""

    resend_period: float  # s of wall-clock time
    last_sent: dict[int, float] = field(default_factory=dict)  # auction id -> wall time
    resends: int = 0

    def sent(self, auction_id: int, now: float) -> None:
        self.last_sent[auction_id] = now

    def due_again(self, now: float, waiting: dict[int, bool]) -> list[int]:
        """Auctions (of `waiting`: id -> some invited robot has not bid) to announce again now."""
        due = []
        for auction_id in list(self.last_sent):
            if auction_id not in waiting:
                del self.last_sent[auction_id]  # closed
            elif waiting[auction_id] and now - self.last_sent[auction_id] >= self.resend_period:
                self.last_sent[auction_id] = now
                self.resends += 1
                due.append(auction_id)
        return due
