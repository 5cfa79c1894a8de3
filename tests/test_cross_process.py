"""Two OS processes exchange a structure over the real ROS 2 middleware.

The talker publishes once with transient_local durability and stays up; the listener starts
afterwards (a late joiner), must still receive it, and rebuilds the same structure.
"""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
from conftest import REPO, STRUCTURES

from tiling_assembly.structure_file import load_structure

pytestmark = pytest.mark.ros


def test_late_joiner_receives_the_latched_structure() -> None:
    path = STRUCTURES / "paper_14.yaml"
    talker = subprocess.Popen(
        [sys.executable, "-m", "tests.ros_helpers.structure_talker", str(path)],
        cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )
    try:
        assert talker.stdout is not None
        assert talker.stdout.readline().strip() == "published"
        listener = subprocess.run(
            [sys.executable, "-m", "tests.ros_helpers.structure_listener", "30"],
            cwd=REPO, capture_output=True, text=True, timeout=60,
        )
        assert listener.returncode == 0, listener.stderr
        received = json.loads(listener.stdout)
    finally:
        talker.terminate()
        try:
            talker.wait(timeout=10)
        except subprocess.TimeoutExpired:
            talker.kill()
            talker.wait()
    expected = load_structure(path)
    assert received["name"] == "paper_14"
    assert received["stamp_sec"] > 0
    assert received["tiles"] == expected.tile_ids
    assert {int(k): tuple(v) for k, v in received["supports"].items()} == expected.supports
