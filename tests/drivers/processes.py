"""Device emulators and driver nodes as real OS processes, for the driver tests.

An :class:`Emulator` runs ``ros2 run hardware_drivers <kind>_emulator`` on a pty whose path the
driver opens; the test injects faults through its standard input and reads its event lines.
A :class:`NodeProcess` runs a driver node with ``ros2 run`` and keeps its log for assertions.
"""

from __future__ import annotations

import os
import queue
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def executable(name: str) -> list[str]:
    """The command `ros2 run hardware_drivers NAME` resolves to."""
    if shutil.which("ros2"):
        return ["ros2", "run", "hardware_drivers", name]
    path = REPO / "install" / "hardware_drivers" / "lib" / "hardware_drivers" / name
    return [sys.executable, str(path)]


class Emulator:
    def __init__(self, kind: str, port: Path, *args: str) -> None:
        self.kind = kind
        self.port = port
        self.lines: list[tuple[float, str]] = []
        self._queue: queue.Queue[tuple[float, str]] = queue.Queue()
        self.process = subprocess.Popen(
            [*executable(f"{kind}_emulator"), "--port", str(port), *args],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, bufsize=1,
        )
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()
        self.wait_for("ready", 20.0)

    def _read(self) -> None:
        assert self.process.stdout is not None
        for line in self.process.stdout:
            item = (time.monotonic(), line.strip())
            self.lines.append(item)
            self._queue.put(item)

    def send(self, line: str) -> None:
        assert self.process.stdin is not None
        self.process.stdin.write(line + "\n")
        self.process.stdin.flush()

    def wait_for(self, prefix: str, timeout: float = 5.0) -> str:
        """The next event line starting with `prefix` (earlier lines are consumed)."""
        deadline = time.monotonic() + timeout
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise AssertionError(f"{self.kind} emulator: no '{prefix}' line within {timeout} s; "
                                     f"last lines: {[text for _, text in self.lines[-8:]]}")
            try:
                _, text = self._queue.get(timeout=remaining)
            except queue.Empty:
                continue
            if text.startswith(prefix):
                return text

    def drain(self) -> None:
        while not self._queue.empty():
            self._queue.get_nowait()

    def true_pose(self) -> tuple[float, float, float]:
        """The Create emulator's true pose (x, y, yaw)."""
        self.drain()
        self.send("pose")
        _, x, y, yaw = self.wait_for("pose ").split()
        return float(x), float(y), float(yaw)

    def close(self) -> None:
        if self.process.poll() is None:
            try:
                self.send("quit")
                self.process.wait(timeout=5)
            except (OSError, subprocess.TimeoutExpired):
                self.process.kill()
                self.process.wait()


class NodeProcess:
    def __init__(self, executable_name: str, log_dir: Path, *ros_args: str, namespace: str = "/robot1",
                 params_files: tuple[str, ...] = ("config/hardware_drivers.yaml",)) -> None:
        self.name = executable_name
        self.log_path = log_dir / f"{executable_name}.log"
        self._log = open(self.log_path, "w")
        command = [*executable(executable_name), "--ros-args", "-r", f"__ns:={namespace}"]
        for params_file in params_files:
            command += ["--params-file", str(REPO / params_file)]
        command += list(ros_args)
        env = {**os.environ, "RCUTILS_CONSOLE_OUTPUT_FORMAT": "[{severity}] [{name}]: {message}"}
        self.process = subprocess.Popen(command, stdout=self._log, stderr=subprocess.STDOUT, cwd=REPO,
                                        env=env)

    def log(self) -> str:
        return self.log_path.read_text()

    def wait_for_log(self, text: str, timeout: float = 15.0, count: int = 1) -> str:
        """The log once `text` appears in it `count` times."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            log = self.log()
            if log.count(text) >= count:
                return log
            if self.process.poll() is not None:
                break
            time.sleep(0.05)
        raise AssertionError(f"{self.name}: '{text}' not logged within {timeout} s; log:\n{self.log()}")

    def stop(self) -> int:
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGINT)
            try:
                self.process.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        self._log.close()
        return self.process.returncode


def wheels_stop(create: Emulator, within: float) -> bool:
    """Whether the Create's last drive command is a stop within `within` s. The stop travels through
    create_base and the serial line, the action's result by another way: it may arrive first."""
    deadline = time.monotonic() + within
    while True:
        drives = [text for _, text in create.lines if text.startswith("drive ")]
        if drives and drives[-1].startswith("drive 0 0"):
            return True
        if time.monotonic() > deadline:
            return False
        time.sleep(0.02)
