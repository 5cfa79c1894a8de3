"""Starting every node as its own OS process and never leaving one behind.

Each process runs in a session of its own (so that it and anything it starts can be signalled as
a group) and is told by the kernel to terminate if the runner dies, even by SIGKILL
(PR_SET_PDEATHSIG). Stopping asks nicely first (SIGINT, as Ctrl-C would, so rclpy shuts down
cleanly), then SIGTERM, then SIGABRT (a hung Python node's stacks into its log), then SIGKILL,
and waits for every one of them.
"""

from __future__ import annotations

import ctypes
import os
import signal
import subprocess
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO

_PR_SET_PDEATHSIG = 1


def _child_setup(nice: int):  # type: ignore[no-untyped-def]
    """What runs in the child before exec: die with the parent; lower the priority if asked."""

    def setup() -> None:
        try:
            ctypes.CDLL("libc.so.6", use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGTERM)
        except OSError:
            pass
        if nice:
            os.nice(nice)

    return setup


@dataclass
class ManagedProcess:
    name: str
    popen: subprocess.Popen[bytes]
    log_path: Path | None
    log_file: IO[bytes] | None

    def alive(self) -> bool:
        return self.popen.poll() is None


@dataclass
class ProcessGroup:
    """The processes of one experiment trial (or one test)."""

    log_dir: Path | None = None
    processes: dict[str, ManagedProcess] = field(default_factory=dict)

    def start(
        self, name: str, argv: Sequence[str], env: Mapping[str, str] | None = None, nice: int = 0
    ) -> ManagedProcess:
        """Start `argv` as `name`; `nice` > 0 lets it yield the CPU to the others (heavy work)."""
        if name in self.processes and self.processes[name].alive():
            raise ValueError(f"a process named {name} is already running")
        log_file = None
        log_path = None
        if self.log_dir is not None:
            self.log_dir.mkdir(parents=True, exist_ok=True)
            log_path = self.log_dir / f"{name}.log"
            log_file = open(log_path, "wb")
        popen = subprocess.Popen(
            list(argv),
            stdin=subprocess.DEVNULL,
            stdout=log_file if log_file else subprocess.DEVNULL,
            stderr=subprocess.STDOUT if log_file else subprocess.DEVNULL,
            env=dict(env) if env is not None else None,
            start_new_session=True,
            preexec_fn=_child_setup(nice),
        )
        process = ManagedProcess(name, popen, log_path, log_file)
        self.processes[name] = process
        return process

    def pids(self) -> list[int]:
        return [p.popen.pid for p in self.processes.values()]

    def dead(self) -> list[str]:
        """Names of processes that exited on their own."""
        return [name for name, p in self.processes.items() if not p.alive()]

    def how_it_ended(self, name: str) -> str:
        """How process `name` ended, for a one-line diagnostic: "exited with code N" or "was killed by
        SIGNAME" (a crash, or a signal from outside the run)."""
        code = self.processes[name].popen.returncode
        if code is None:
            return "is still running"
        if code < 0:
            try:
                return f"was killed by {signal.Signals(-code).name}"
            except ValueError:
                return f"was killed by signal {-code}"
        return f"exited with code {code}"

    def kill(self, name: str) -> None:
        """Kill one process at once, as a crash would (SIGKILL to its whole session)."""
        process = self.processes[name]
        _signal_group(process.popen.pid, signal.SIGKILL)
        process.popen.wait()

    def stop(self, grace: float = 5.0, term_grace: float = 10.0) -> dict[str, int]:
        """Stop every process: SIGINT, then SIGTERM, then SIGKILL; wait for all of them. The
        defaults are `ros2 launch`'s (SIGTERM 5 s after SIGINT, SIGKILL 10 s after that): a node
        stops within them (tiling_ros.spinning), so it must within the experiment's too.

        Returns the exit code of every process that was still running and did not exit cleanly
        (0) when asked: a node that needed SIGTERM or SIGKILL, or crashed on its way out."""
        asked = [name for name, p in self.processes.items() if p.alive()]
        # SIGABRT before SIGKILL: a Python process started with PYTHONFAULTHANDLER set (the
        # experiment's nodes are) writes every thread's stack to its log, where it hangs
        for sig, wait in ((signal.SIGINT, grace), (signal.SIGTERM, term_grace), (signal.SIGABRT, 2.0),
                          (signal.SIGKILL, 2.0)):
            running = [p for p in self.processes.values() if p.alive()]
            if not running:
                break
            for process in running:
                _signal_group(process.popen.pid, sig)
            deadline = time.monotonic() + wait
            while time.monotonic() < deadline and any(p.alive() for p in running):
                time.sleep(0.02)
        for process in self.processes.values():
            # the session may hold grandchildren even after its leader exited
            _signal_group(process.popen.pid, signal.SIGKILL)
            try:
                process.popen.wait(timeout=2.0)
            except subprocess.TimeoutExpired:
                pass
            if process.log_file is not None:
                process.log_file.close()
        codes = {name: self.processes[name].popen.returncode for name in asked}
        self.processes.clear()
        return {name: code for name, code in codes.items() if code != 0}

    def __enter__(self) -> ProcessGroup:
        return self

    def __exit__(self, *_exc: object) -> None:
        self.stop()


def _signal_group(pid: int, sig: signal.Signals) -> None:
    try:
        os.killpg(pid, sig)
    except (ProcessLookupError, PermissionError):
        pass


def session_members(session_ids: Sequence[int]) -> list[int]:
    """PIDs of every live process in the given sessions (for checking that nothing is left)."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        state, session = fields[0], int(fields[3])
        if session in session_ids and state != "Z":
            found.append(int(entry.name))
    return found
