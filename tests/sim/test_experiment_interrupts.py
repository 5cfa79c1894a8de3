"""Ctrl-C that lands inside a C++ binding still ends an experiment as an interrupt."""

from __future__ import annotations

from pathlib import Path

import pytest
from conftest import STRUCTURES

from tiling_assembly import interrupts
from tiling_sim import experiment


@pytest.fixture(autouse=True)
def _leave_the_test_process_as_it_is(monkeypatch: pytest.MonkeyPatch) -> None:
    """pytest's signal handlers, its ROS domain and the session's default ROS context (another
    test's probe uses it)."""
    monkeypatch.setattr(experiment, "raise_keyboard_interrupt_on_signals", lambda: None)
    monkeypatch.setattr(experiment, "isolate", lambda domain: None)
    monkeypatch.setattr(experiment.rclpy, "init", lambda **_: None)
    monkeypatch.setattr(experiment.rclpy, "try_shutdown", lambda **_: None)


def test_a_ctrl_c_a_binding_turned_into_another_error_still_counts_as_an_interrupt(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    """pybind11 turns a KeyboardInterrupt raised while it converts a call's arguments into a
    RuntimeError; the experiment reported "error: Unable to convert call argument '0' ..." and
    exit code 2 for a Ctrl-C (tests/e2e, once in a fresh-clone run)."""

    def interrupted_inside_a_binding(self: experiment.Experiment) -> None:
        interrupts.signalled.set()
        raise RuntimeError("Unable to convert call argument '0' to Python object")

    monkeypatch.setattr(experiment.Experiment, "run", interrupted_inside_a_binding)
    try:
        code = experiment.main(["--structure", str(STRUCTURES / "paper_14.yaml"), "--report", str(tmp_path),
                                "--trials", "1", "--quiet"])
    finally:
        interrupts.signalled.clear()
    assert code == 130
    assert "interrupted: every node was stopped" in capsys.readouterr().err


def test_the_same_error_without_a_signal_is_reported_as_an_error(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    def broken(self: experiment.Experiment) -> None:
        raise RuntimeError("something else broke")

    monkeypatch.setattr(experiment.Experiment, "run", broken)
    code = experiment.main(["--structure", str(STRUCTURES / "paper_14.yaml"), "--report", str(tmp_path),
                            "--trials", "1", "--quiet"])
    assert code == 2
    assert capsys.readouterr().err.strip() == "error: something else broke"


HANGING_SHUTDOWN = """
import sys, threading
from tiling_assembly import interrupts
from tiling_sim import experiment
experiment.raise_keyboard_interrupt_on_signals = lambda: None
experiment.isolate = lambda domain: None
experiment.rclpy.init = lambda **_: None
experiment.rclpy.try_shutdown = lambda **_: threading.Event().wait()  # a locked shared-memory port
experiment.ROS_SHUTDOWN_PATIENCE = 1.0
def interrupted(self):
    raise KeyboardInterrupt
experiment.Experiment.run = interrupted
sys.exit(experiment.main(sys.argv[1:]))
"""


def test_the_experiment_ends_with_its_exit_code_when_ros_never_shuts_down(tmp_path: Path) -> None:
    """Stopping 8 robots and 2 VI robots once left the experiment itself blocked in Fast DDS's
    teardown (a killed node's shared-memory port stayed locked): it exits anyway, with its code."""
    import subprocess
    import sys
    import time

    from conftest import REPO

    started = time.monotonic()
    done = subprocess.run([sys.executable, "-c", HANGING_SHUTDOWN, "--structure", str(STRUCTURES / "paper_14.yaml"),
                           "--report", str(tmp_path), "--trials", "1", "--quiet"],
                          cwd=REPO, capture_output=True, text=True, timeout=60)
    assert done.returncode == 130, done.stderr
    assert "interrupted: every node was stopped" in done.stderr
    assert "experiment: ROS did not shut down within 1 s; exiting without it" in done.stderr
    assert time.monotonic() - started < 30
