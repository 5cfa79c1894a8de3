"""Shared test set-up: an isolated ROS 2 domain per test session, and paths.

Every test session claims a ROS_DOMAIN_ID of its own (a lock file per domain id, held for the
session) and keeps discovery on this host, so parallel sessions on one machine never cross-talk.
The variables are set at import time so that every process a test starts inherits them.
"""

from __future__ import annotations

import fcntl
import os
from pathlib import Path
from typing import IO

import pytest

REPO = Path(__file__).resolve().parent.parent
STRUCTURES = REPO / "config" / "structures"
DATA = Path(__file__).resolve().parent / "data"


def _claim_domain_id() -> tuple[int, IO[str]]:
    start = os.getpid() % 100
    for k in range(100):
        domain = 1 + (start + k) % 100
        handle = open(f"/tmp/tiling_assembly_test_domain_{domain}.lock", "w")  # noqa: SIM115
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            handle.close()
            continue
        return domain, handle
    raise RuntimeError("every ROS domain id 1-100 is taken by another test session")


_DOMAIN_ID, _DOMAIN_LOCK = _claim_domain_id()
os.environ["ROS_DOMAIN_ID"] = str(_DOMAIN_ID)
os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
os.environ.setdefault("RCUTILS_COLORIZED_OUTPUT", "0")
os.environ["PYTHONUNBUFFERED"] = "1"


def pytest_report_header(config: pytest.Config) -> str:
    return f"ROS_DOMAIN_ID={_DOMAIN_ID} (claimed for this session), discovery on localhost only"


@pytest.fixture(scope="session")
def ros_domain_id() -> int:
    return _DOMAIN_ID
