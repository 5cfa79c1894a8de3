"""planner_node over the real ROS 2 middleware, each party its own OS process: a subscriber that
joins after the plan was published still gets it (transient_local), and /replan called from
another process returns a valid plan for the tiles left and republishes it with revision + 1."""

from __future__ import annotations

import json
import os
import queue
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from conftest import DATA, REPO, STRUCTURES
from planner_checks import plan_problems

from tiling_assembly.structure_file import load_structure
from tiling_assembly.time_model import TimeModel

pytestmark = pytest.mark.ros

PAPER = STRUCTURES / "paper_14.yaml"
ENV = {**os.environ, "RCUTILS_LOGGING_BUFFERED_STREAM": "0", "PYTHONUNBUFFERED": "1"}


def helper(module: str, *args: str) -> dict:
    result = subprocess.run(
        [sys.executable, "-m", f"tests.planner.{module}", *args],
        cwd=REPO, capture_output=True, text=True, timeout=90, env=ENV,
    )
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout)


class NodeProcess:
    """planner_node started with `ros2 run`, its log lines collected as they come."""

    def __init__(self, *parameters: str, ros_args: tuple[str, ...] = ()) -> None:
        args = ["ros2", "run", "planner_node", "planner_node", "--ros-args", *ros_args]
        for p in parameters:
            args += ["-p", p]
        self.process = subprocess.Popen(
            args, cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=ENV
        )
        self.lines: queue.Queue[str] = queue.Queue()
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        assert self.process.stdout is not None
        for line in self.process.stdout:
            self.lines.put(line)

    def wait_for(self, text: str, timeout: float = 60.0) -> str:
        deadline = time.monotonic() + timeout
        seen = []
        while time.monotonic() < deadline:
            try:
                line = self.lines.get(timeout=0.2)
            except queue.Empty:
                if self.process.poll() is not None:
                    break
                continue
            seen.append(line)
            if text in line:
                return line
        raise AssertionError(f"no '{text}' from planner_node; it said: {''.join(seen)}")

    def stop(self) -> None:
        self.process.terminate()
        try:
            self.process.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()


def test_late_subscriber_gets_the_plan_and_replan_serves_the_rest(tmp_path: Path) -> None:
    structure = load_structure(PAPER)
    team = tmp_path / "team.yaml"
    team.write_text("/**:\n  ros__parameters:\n    robot_names: [alpha, beta]\n    improve_time_limit: 0.2\n")
    # the shipped parameter file, then the lab's own; in a namespace, to show the wildcard works
    node = NodeProcess(
        f"structure_file:={PAPER}",
        ros_args=("-r", "__ns:=/lab", "--params-file", str(REPO / "config" / "planner_node.yaml"),
                  "--params-file", str(team)),
    )
    try:
        node.wait_for("published plan revision 0")
        first = helper("plan_listener", "--timeout", "30")  # joins after the plan was published
        plan = first["plan"]
        assert first["structure"] == {"name": "paper_14", "tiles": sorted(structure.tiles)}
        assert plan["revision"] == 0 and plan["method"] == "default" and plan["stamp_sec"] > 0
        assert [t["robot"] for t in plan["tasks"]] == ["alpha", "beta"]
        orders = {t["robot"]: t["tiles"] for t in plan["tasks"]}
        assert plan_problems(structure, orders, TimeModel()) == []
        assert plan["makespan"] >= plan["lower_bound"] > 0
        assert {int(k): tuple(v) for k, v in plan["supports"].items()} == dict(structure.supports)

        # beta died after the base was laid: alpha gets everything that is left
        placed = [1, 2, 3, 6, 7]
        reply = helper("replan_client", "--placed", ",".join(map(str, placed)), "--robots", "alpha")
        assert reply["success"] and reply["message"] == ""
        assert reply["revision"] == 1
        assert [t["robot"] for t in reply["tasks"]] == ["alpha"]
        rest = structure.subset(t for t in structure.tiles if t not in placed)
        assert sorted(reply["tasks"][0]["tiles"]) == sorted(rest.tiles)
        assert plan_problems(rest, {"alpha": reply["tasks"][0]["tiles"]}, TimeModel()) == []
        assert reply["makespan"] == pytest.approx(TimeModel().workload(structure, rest.tiles))

        for args, why in (
            (["--placed", "1,99"], "99"),
            (["--robots", "alpha,robot9"], "unknown robot 'robot9'"),
        ):
            refused = helper("replan_client", *args)
            assert not refused["success"] and why in refused["message"]

        latest = helper("plan_listener", "--revision", "1", "--timeout", "30")["plan"]
        assert latest["revision"] == 1
        assert [t["tiles"] for t in latest["tasks"]] == [t["tiles"] for t in reply["tasks"]]
        assert node.process.poll() is None  # refused requests did not take the node down
    finally:
        node.stop()


def test_node_refuses_a_bad_structure_file_with_one_line() -> None:
    bad = DATA / "structures" / "invalid" / "floating_tile.yaml"
    result = subprocess.run(
        ["ros2", "run", "planner_node", "planner_node", "--ros-args", "-p", f"structure_file:={bad}"],
        cwd=REPO, capture_output=True, text=True, timeout=60, env=ENV,
    )
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: {bad}: floating")
