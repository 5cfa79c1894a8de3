"""Shared test set-up: an isolated ROS 2 domain per test session, paths, and node processes.

Every test session claims a ROS_DOMAIN_ID of its own (a lock file per domain id, held for the
session) and keeps discovery on this host, so parallel sessions on one machine never cross-talk.
The variables are set at import time so that every process a test starts inherits them.

A test that hangs inside a C call holding the GIL is out of pytest-timeout's reach; pytest's
faulthandler, whose watchdog needs no interpreter, then ends the session with every thread's stack
(`faulthandler_timeout` in pyproject.toml). The session ends without the interpreter's clean-up,
which would tear the middleware down (see `ros_helpers.isolated_domains`).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
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


_SESSION = pytest.StashKey[pytest.Session]()


def pytest_sessionfinish(session: pytest.Session) -> None:
    session.config.stash[_SESSION] = session


@pytest.hookimpl(trylast=True)
def pytest_unconfigure(config: pytest.Config) -> None:
    session = config.stash.get(_SESSION, None)
    if session is None:
        return
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(int(session.exitstatus))


@pytest.fixture(scope="session")
def ros_domain_id() -> int:
    return _DOMAIN_ID


def ros2_command() -> str:
    """The real `ros2` where there is one, else the workspace's minimal `ros2 run`."""
    if any((Path(p) / "ros2").exists() for p in os.environ.get("PATH", "").split(os.pathsep)):
        return "ros2"
    return str(REPO / "tools" / "ros2")


def stop_node_process(process: subprocess.Popen[str]) -> str:
    """Ctrl-C a node started by a test and check that it stopped cleanly (exit code 0 within 10 s,
    no traceback, no abort); its output."""
    process.send_signal(signal.SIGINT)
    try:
        output, _ = process.communicate(timeout=10)
    except subprocess.TimeoutExpired:
        process.kill()
        output, _ = process.communicate()
    output = output or ""
    assert process.returncode == 0, f"the node exited with {process.returncode} at Ctrl-C:\n{output[-3000:]}"
    for noise in ("Traceback", "terminate called"):
        assert noise not in output, output[-3000:]
    return output


def stop_node_processes(processes: dict[str, subprocess.Popen[str]]) -> dict[str, str]:
    """`stop_node_process` for every one of `processes`, even after one failed to stop cleanly (a
    process left running keeps publishing /clock on a ROS domain the next test may claim); their
    output by name."""
    outputs, failures = {}, []
    for name, process in processes.items():
        try:
            outputs[name] = stop_node_process(process)
        except AssertionError as failure:
            failures.append(f"{name}: {failure}")
    assert not failures, "\n".join(failures)
    return outputs
