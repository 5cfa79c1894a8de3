"""Shared test set-up: an isolated ROS 2 domain per test session, and paths.

Every test session claims a ROS_DOMAIN_ID of its own (a lock file per domain id, held for the
session) and keeps discovery on this host, so parallel sessions on one machine never cross-talk.
The variables are set at import time so that every process a test starts inherits them.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from tiling_sim.ros_domain import claim_domain_id, isolate

REPO = Path(__file__).resolve().parent.parent
STRUCTURES = REPO / "config" / "structures"
DATA = Path(__file__).resolve().parent / "data"


_DOMAIN_ID, _DOMAIN_LOCK = claim_domain_id()
isolate(_DOMAIN_ID)
os.environ.setdefault("RCUTILS_COLORIZED_OUTPUT", "0")
os.environ["PYTHONUNBUFFERED"] = "1"


def pytest_report_header(config: pytest.Config) -> str:
    return f"ROS_DOMAIN_ID={_DOMAIN_ID} (claimed for this session), discovery on localhost only"


@pytest.fixture(scope="session")
def ros_domain_id() -> int:
    return _DOMAIN_ID
