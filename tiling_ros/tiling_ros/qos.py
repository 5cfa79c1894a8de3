"""Every QoS profile of the team's topics, named for what it carries; built here only.

Latched (reliable + transient local) topics keep what they last said for whoever joins late.
Readers of repeated or periodic messages read best effort, though the writers send reliably: a
reliable reader holds every later sample back until DDS repairs a lost one (at the writer's next
heartbeat, seconds by default), so over a lossy link one lost heartbeat made a robot look dead. A
lost heartbeat is replaced by the next one; a lost auction message by its next copy (the sender
repeats it until answered).
"""

from __future__ import annotations

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

# -- the team ---------------------------------------------------------------------------------------
# /structure and /plan: the latest one, for late joiners too
LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE)
# /placement_reports: the whole history, for late joiners too
REPORTS = QoSProfile(depth=1000, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE)
# auction messages, tile states and heartbeats as sent (reliably)
COORDINATION = QoSProfile(depth=50, reliability=ReliabilityPolicy.RELIABLE)
# /auction/decisions: one line per decision, kept for a late reader
DECISIONS = QoSProfile(depth=200, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE)
# reading /robot_status and /auction/status: the latest heartbeats count. The topic has no key, so its
# writers share one history: at depth 1, of 8 robots' heartbeats that came between two takes of a busy
# reader only the last robot's was left, and the others looked dead (an 8-robot trial on 2 cores lost
# robot5 7 times, each time a replan and another when it was "back"). Room for every robot's.
HEARTBEATS = QoSProfile(depth=64, reliability=ReliabilityPolicy.BEST_EFFORT)
# reading announcements, awards, bids and acceptances: each is sent again until answered
REPEATED = QoSProfile(depth=50, reliability=ReliabilityPolicy.BEST_EFFORT)

# -- devices ----------------------------------------------------------------------------------------
DIAGNOSTICS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
# REP 2003: sensor drivers publish reliable, so best-effort and reliable subscribers both connect
SENSOR_PUBLISHER = QoSProfile(depth=5, reliability=ReliabilityPolicy.RELIABLE)
# reading another robot's overhead_pose: the latest poses, whatever its publisher offers
OTHER_ROBOT_POSES = QoSProfile(depth=10, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.BEST_EFFORT)


def sensor_stream(depth: int, reliability: ReliabilityPolicy) -> QoSProfile:
    """Reading a sensor stream (clouds, overhead poses) with the reliability its publishers allow."""
    return QoSProfile(depth=depth, history=HistoryPolicy.KEEP_LAST, reliability=reliability)


# -- the simulated testbed (tiling_sim) ------------------------------------------------------------
# /clock: a body must get every tick, in order, also when its process stalls; a queue of 10 (0.2 s of
# wall time at clock_step 0.02) dropped the ticks of a longer stall. Both ends keep 50 s of ticks (at 0.05).
CLOCK_DEPTH = 1000
CLOCK = QoSProfile(depth=CLOCK_DEPTH, reliability=ReliabilityPolicy.RELIABLE)
# /sim/motion: where a base stands from when is absolute, so a world that joins late may hear it late,
# never lose it
SIM_MOTION = QoSProfile(depth=10, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE)
# /sim/scan_progress: a scan's fate
SIM_SCAN_PROGRESS = QoSProfile(depth=20, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                               reliability=ReliabilityPolicy.RELIABLE)
# /sim/events and /sim/start: every event of a trial, for a runner that joins late too
SIM_EVENTS = QoSProfile(depth=1000, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                        reliability=ReliabilityPolicy.RELIABLE)
# the simulated Kinect's clouds: the latest one, delivered whole
SIM_CAMERA = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE)
# replaying a bag: every message as recorded
REPLAY = QoSProfile(depth=10, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.RELIABLE)
