"""How long ROS 2 data takes to flow again after a link outage between two virtual hosts (a measurement,
not a test; needs root).

    tools/workspace-env python tests/sim/measure_dds_outage.py OUTAGE_S [LOSS_PERCENT [RATE_MBIT]]

A talker on host "robot" (link shaped by LOSS_PERCENT / RATE_MBIT) publishes every 0.1 s to a
listener on the unshaped host "base"; once 20 messages have arrived the robot's link is cut for
OUTAGE_S seconds. Prints how many messages arrived during the outage, how long after link-up the
first one came, and which one it was (the numbers the talker published while the link was out are
repaired from its history only if the outage was shorter than Fast DDS's 20 s participant lease).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

from tiling_sim.ros_domain import claim_domain_id
from tiling_sim.virtual_hosts import LinkShape, VirtualHosts

PEER = [sys.executable, str(Path(__file__).resolve().parent / "virtual_hosts_peer.py")]


def main() -> None:
    outage = float(sys.argv[1])
    loss = float(sys.argv[2]) if len(sys.argv) > 2 else 0.0
    rate = float(sys.argv[3]) if len(sys.argv) > 3 else None
    domain, _lock = claim_domain_id()
    os.environ["ROS_DOMAIN_ID"] = str(domain)
    with VirtualHosts("outage-measure") as hosts:
        robot = hosts.add_host("robot", LinkShape(loss_percent=loss, rate_mbit=rate))
        base = hosts.add_host("base")
        listener = subprocess.Popen(hosts.command(base, [*PEER, "listen"]), env=hosts.host_environment(base),
                                    stdout=subprocess.PIPE, text=True)  # fmt: skip
        talker = subprocess.Popen(hosts.command(robot, [*PEER, "talk", "0.1"]), env=hosts.host_environment(robot))
        arrivals: list[tuple[int, float]] = []

        def read() -> None:
            assert listener.stdout is not None
            for line in listener.stdout:
                if line.startswith("chatter"):
                    _, number, at = line.split()
                    arrivals.append((int(number), float(at)))

        threading.Thread(target=read, daemon=True).start()
        try:
            while len(arrivals) < 20:
                time.sleep(0.05)
            cut = time.monotonic()
            hosts.set_link(robot, False)
            time.sleep(outage)
            restored = time.monotonic()
            hosts.set_link(robot, True)
            while not [a for a in arrivals if a[1] > restored] and time.monotonic() - restored < 60:
                time.sleep(0.02)
            during = [a for a in arrivals if cut + 0.2 < a[1] < restored]
            after = [a for a in arrivals if a[1] > restored]
            shape = LinkShape(loss_percent=loss, rate_mbit=rate)
            if after:
                print(f"{outage:g} s outage, robot link {shape}: {len(during)} messages during it; the first after "
                      f"link-up came {after[0][1] - restored:.2f} s later (message {after[0][0]}, "
                      f"{len(arrivals) - len(after)} arrived before link-up)")  # fmt: skip
            else:
                print(f"{outage:g} s outage, robot link {shape}: nothing arrived within 60 s of link-up")
            print(hosts.counters(robot))
        finally:
            for process in (talker, listener):
                process.send_signal(signal.SIGINT)
            for process in (talker, listener):
                process.wait(timeout=15)


if __name__ == "__main__":
    main()
