"""`ros2 run tiling_sim replay_bag`: publish a rosbag2's messages over ROS, like `ros2 bag play`.

    ros2 run tiling_sim replay_bag --bag DIR [--rate R] [--topics T,T] [--wait-subscribers SECONDS]
        [--gap SECONDS]

For workspaces without the rosbag2 tools (the PyPI ROS wheels): reads the bag with `rosbags` and
publishes every message's recorded CDR bytes unchanged (no conversion, header stamps as recorded)
on its topic with its type, paced by the recorded receive times divided by `--rate` (0: as fast as
possible, or `--gap` seconds apart). With `--wait-subscribers`, waits up to that long until every
topic has a subscriber before starting. Prints one line per published message to stdout (topic,
stamp) and a summary line; bad arguments or bags: one line on stderr, exit status 2 or 1.
"""

from __future__ import annotations

import argparse
import importlib
import sys
import time
from pathlib import Path
from typing import Any

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node

from tiling_ros.qos import REPLAY


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # type: ignore[override]
        print(f"error: {message}", file=sys.stderr)
        raise SystemExit(2)


def message_class(type_name: str) -> Any:
    """The rclpy class of 'pkg/msg/Type'."""
    package, kind, name = type_name.split("/")
    return getattr(importlib.import_module(f"{package}.{kind}"), name)


def main(argv: list[str] | None = None) -> int:
    parser = _Parser(
        prog="ros2 run tiling_sim replay_bag", description="Publish a rosbag2's messages over ROS."
    )
    parser.add_argument("--bag", required=True, help="rosbag2 folder (MCAP or SQLite)")
    parser.add_argument("--rate", type=float, default=1.0, help="playback speed factor (0: no pacing)")
    parser.add_argument("--gap", type=float, default=0.0, help="with --rate 0: seconds between messages")
    parser.add_argument("--topics", default="", help="comma-separated topics to publish (default: all)")
    parser.add_argument(
        "--start-delay", type=float, default=0.0, help="seconds to wait before the first message"
    )
    parser.add_argument("--linger", type=float, default=1.0, help="seconds to stay up after the last message")
    parser.add_argument(
        "--wait-subscribers", type=float, default=0.0, help="wait up to this long for subscribers"
    )
    args = parser.parse_args(argv)
    if min(args.rate, args.gap, args.wait_subscribers, args.linger, args.start_delay) < 0:
        print(
            "error: --rate, --gap, --start-delay, --linger and --wait-subscribers must not be negative",
            file=sys.stderr,
        )
        return 2

    from rosbags.rosbag2 import Reader, ReaderError

    path = Path(args.bag)
    if not path.is_dir():
        print(f"error: {path}: not a rosbag2 folder", file=sys.stderr)
        return 1
    wanted = {t for t in args.topics.split(",") if t}
    rclpy.init()
    node = Node("replay_bag")
    published = 0
    try:
        with Reader(path) as reader:
            connections = [c for c in reader.connections if not wanted or c.topic in wanted]
            publishers: dict[str, Any] = {}
            for c in connections:
                if c.topic in publishers:
                    continue
                try:
                    kind = message_class(c.msgtype)
                except (ImportError, AttributeError, ValueError):
                    print(f"error: message type {c.msgtype} of {c.topic} is not installed", file=sys.stderr)
                    return 1
                publishers[c.topic] = node.create_publisher(kind, c.topic, REPLAY)
            deadline = time.monotonic() + args.wait_subscribers
            while args.wait_subscribers and time.monotonic() < deadline:
                if all(p.get_subscription_count() > 0 for p in publishers.values()):
                    break
                rclpy.spin_once(node, timeout_sec=0.05)
            time.sleep(args.start_delay)  # subscribers may still be settling their QoS
            start_wall, start_bag = time.monotonic(), None
            for connection, timestamp, raw in reader.messages(connections=connections):
                if start_bag is None:
                    start_bag = timestamp
                if args.rate > 0:
                    due = start_wall + (timestamp - start_bag) / 1e9 / args.rate
                    while (wait := due - time.monotonic()) > 0:
                        time.sleep(min(wait, 0.05))
                elif args.gap > 0 and published:
                    time.sleep(args.gap)
                publishers[connection.topic].publish(bytes(raw))
                published += 1
                print(f"{connection.topic} {timestamp}", flush=True)
            time.sleep(args.linger)  # let the middleware hand the last messages over before exiting
    except ReaderError as error:
        print(f"error: {path}: cannot read the bag: {error}", file=sys.stderr)
        return 1
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    print(f"published {published} messages", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
