"""Processes of a run are stopped, and die with their runner even when it is killed."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

from tiling_sim.process_group import ProcessGroup, session_members


def _wait_gone(pids: list[int], timeout: float = 5.0) -> list[int]:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        alive = session_members(pids)
        if not alive:
            return []
        time.sleep(0.05)
    return session_members(pids)


def test_stop_ends_every_process_and_its_children(tmp_path: Path) -> None:
    group = ProcessGroup(log_dir=tmp_path)
    # a shell that ignores SIGINT and SIGTERM and has a child of its own: only SIGKILL works
    stubborn = "trap '' INT TERM; sleep 60 & wait"
    group.start("stubborn", ["bash", "-c", stubborn])
    group.start("polite", [sys.executable, "-c", "import time; print('up', flush=True); time.sleep(60)"])
    time.sleep(0.3)
    sessions = group.pids()
    assert len(session_members(sessions)) >= 3
    started = time.monotonic()
    group.stop(grace=0.5, term_grace=2.0)
    assert time.monotonic() - started < 8.0
    assert _wait_gone(sessions) == []
    assert (tmp_path / "polite.log").read_text().startswith("up")  # its output went to its log


def test_children_die_when_the_runner_is_killed(tmp_path: Path) -> None:
    runner = textwrap.dedent(
        f"""
        import sys, time
        sys.path[:0] = {sys.path!r}
        from tiling_sim.process_group import ProcessGroup
        group = ProcessGroup()
        group.start("child", ["sleep", "60"])
        print(group.pids()[0], flush=True)
        time.sleep(60)
        """
    )
    parent = subprocess.Popen([sys.executable, "-c", runner], stdout=subprocess.PIPE, text=True)
    assert parent.stdout is not None
    child = int(parent.stdout.readline())
    assert session_members([child])
    os.kill(parent.pid, signal.SIGKILL)  # no clean-up code runs
    parent.wait()
    assert _wait_gone([child]) == []


def test_kill_stops_one_process_at_once(tmp_path: Path) -> None:
    with ProcessGroup() as group:
        group.start("a", ["sleep", "60"])
        group.start("b", ["sleep", "60"])
        group.kill("a")
        assert group.dead() == ["a"]
        assert group.how_it_ended("a") == "was killed by SIGKILL" and group.how_it_ended("b") == "is still running"
        sessions = group.pids()
    assert _wait_gone(sessions) == []


def test_stop_reports_the_processes_that_did_not_exit_cleanly(tmp_path: Path) -> None:
    def on_ctrl_c(action: str) -> list[str]:
        return [sys.executable, "-c", f"import os, time\ntry:\n time.sleep(60)\nexcept KeyboardInterrupt:\n {action}"]

    group = ProcessGroup(log_dir=tmp_path)
    group.start("clean", on_ctrl_c("pass"))
    group.start("crashes", on_ctrl_c("os.abort()"))
    group.start("deaf", ["bash", "-c", "trap '' INT; sleep 60"])
    group.start("gone", ["true"])
    time.sleep(0.5)
    assert group.stop(grace=1.0, term_grace=2.0) == {"crashes": -signal.SIGABRT, "deaf": -signal.SIGTERM}


def test_a_hung_python_process_leaves_its_stacks_in_its_log(tmp_path: Path) -> None:
    """What the experiment needs to find why a node did not stop: SIGABRT before SIGKILL, and the
    node's faulthandler (PYTHONFAULTHANDLER) writes where every thread was."""
    group = ProcessGroup(log_dir=tmp_path)
    hung = ("import signal, time\n"
            "signal.signal(signal.SIGINT, signal.SIG_IGN); signal.signal(signal.SIGTERM, signal.SIG_IGN)\n"
            "def stuck_in_shutdown():\n    time.sleep(60)\n"
            "print('up', flush=True); stuck_in_shutdown()\n")
    group.start("hung", [sys.executable, "-c", hung], env={**os.environ, "PYTHONFAULTHANDLER": "1"})
    deadline = time.monotonic() + 10.0
    while "up" not in (tmp_path / "hung.log").read_text() and time.monotonic() < deadline:
        time.sleep(0.05)
    assert group.stop(grace=0.3, term_grace=2.0) == {"hung": -signal.SIGABRT}
    log = (tmp_path / "hung.log").read_text()
    assert "Fatal Python error: Aborted" in log and "stuck_in_shutdown" in log, log


def test_how_a_process_ended_is_told_by_its_exit_code_or_signal() -> None:
    with ProcessGroup() as group:
        group.start("fails", ["bash", "-c", "exit 3"])
        group.start("crashes", [sys.executable, "-c", "import os, signal; os.kill(os.getpid(), signal.SIGSEGV)"])
        for process in group.processes.values():
            process.popen.wait(timeout=10)
        assert group.how_it_ended("fails") == "exited with code 3"
        assert group.how_it_ended("crashes") == "was killed by SIGSEGV"
