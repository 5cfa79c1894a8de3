"""Owns a few virtual hosts with a process on each, prints what it made as one JSON line, then waits
to be signalled (tests/sim/test_virtual_hosts.py checks that nothing of it outlives it).

    virtual_hosts_owner.py RUN_ID
"""

from __future__ import annotations

import json
import os
import sys
import time

from tiling_sim.process_group import ProcessGroup
from tiling_sim.virtual_hosts import LinkShape, VirtualHosts


def main() -> None:
    with VirtualHosts(sys.argv[1]) as hosts, ProcessGroup() as group:
        robot = hosts.add_host("robot", LinkShape(loss_percent=5.0, rate_mbit=5.0))
        base = hosts.add_host("base")
        far = hosts.add_host("far", LinkShape(delay_ms=20.0))
        hosts.set_link(robot, False)
        for host in (robot, base, far):
            group.start(host.name, hosts.command(host, ["sleep", "60"]))
        made = {
            "keepers": hosts.keeper_pids,
            "namespaces": [os.stat(f"/proc/{pid}/ns/net").st_ino for pid in hosts.keeper_pids],
            "processes": group.pids() + hosts.delay_line_pids,
        }
        print(json.dumps(made), flush=True)
        time.sleep(60)


if __name__ == "__main__":
    try:
        main()
    except KeyboardInterrupt:
        sys.exit(0)
