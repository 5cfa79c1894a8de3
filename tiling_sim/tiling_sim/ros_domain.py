"""A private ROS 2 domain for a simulated run, so that it never talks to real robots.

The simulation publishes the same topics as the real robots. Run on a machine that also drives
robots (or next to another simulation), it must not join their graph: every run claims a domain
id no other run on this host holds (a lock file per id, held for the life of the run) and keeps
discovery on the local host.
"""

from __future__ import annotations

import fcntl
import os
from typing import IO

FIRST, LAST = 101, 200  # ids tests and experiments use; 0 (the default) is left to real systems


def claim_domain_id(first: int = FIRST, last: int = LAST) -> tuple[int, IO[str]]:
    """A free domain id and the open lock file that holds it (keep it open while using the id)."""
    span = last - first + 1
    start = os.getpid() % span
    for k in range(span):
        domain = first + (start + k) % span
        handle = open(f"/tmp/tiling_assembly_ros_domain_{domain}.lock", "w")
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            handle.close()
            continue
        return domain, handle
    raise RuntimeError(f"every ROS domain id {first}-{last} is held by another run on this host")


def isolate(domain: int) -> None:
    """Use `domain` and localhost-only discovery in this process and every process it starts."""
    os.environ["ROS_DOMAIN_ID"] = str(domain)
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
