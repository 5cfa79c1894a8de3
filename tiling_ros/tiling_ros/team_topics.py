"""The team's topics, each with its name, message type and QoS written once, so that every node
that writes or reads one agrees on all three (QoS profiles and why: `tiling_ros.qos`)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.qos import QoSProfile
from rclpy.subscription import Subscription
from std_msgs.msg import String

from tiling_assembly_msgs.msg import (
    AssemblyPlan,
    AuctionAcceptance,
    AuctionAnnouncement,
    AuctionAward,
    AuctionBid,
    AuctioneerStatus,
    PlacementReport,
    RobotStatus,
    Structure,
    TileStateArray,
)
from tiling_ros.qos import COORDINATION, DECISIONS, HEARTBEATS, LATCHED, REPEATED, REPORTS


@dataclass(frozen=True)
class TeamTopic:
    """One topic of the team: writers send with `writer_qos`, readers read with `reader_qos`."""

    name: str
    msg_type: Any
    writer_qos: QoSProfile
    reader_qos: QoSProfile

    def publisher(self, node: Node) -> Publisher:
        return node.create_publisher(self.msg_type, self.name, self.writer_qos)

    def subscribe(self, node: Node, callback: Callable[[Any], None]) -> Subscription:
        return node.create_subscription(self.msg_type, self.name, callback, self.reader_qos)


STRUCTURE = TeamTopic("/structure", Structure, LATCHED, LATCHED)
PLAN = TeamTopic("/plan", AssemblyPlan, LATCHED, LATCHED)
PLACEMENT_REPORTS = TeamTopic("/placement_reports", PlacementReport, REPORTS, REPORTS)
TILE_STATES = TeamTopic("/tile_states", TileStateArray, COORDINATION, COORDINATION)
ROBOT_STATUS = TeamTopic("/robot_status", RobotStatus, COORDINATION, HEARTBEATS)
AUCTIONEER_STATUS = TeamTopic("/auction/status", AuctioneerStatus, COORDINATION, HEARTBEATS)
ANNOUNCEMENTS = TeamTopic("/auction/announcements", AuctionAnnouncement, COORDINATION, REPEATED)
AWARDS = TeamTopic("/auction/awards", AuctionAward, COORDINATION, REPEATED)
BIDS = TeamTopic("/auction/bids", AuctionBid, COORDINATION, REPEATED)
ACCEPTANCES = TeamTopic("/auction/acceptances", AuctionAcceptance, COORDINATION, REPEATED)
DECISIONS_LOG = TeamTopic("/auction/decisions", String, DECISIONS, DECISIONS)
