"""The common machinery of the device emulators: a pseudo-terminal posing as a USB serial device.

The emulator holds the master side of a pty and publishes the slave side under a fixed path (a
symlink, e.g. ``/tmp/m3/create``); the driver opens that path with pyserial exactly as it would
open ``/dev/ttyUSB0``. Unplugging closes the pty and removes the path, plugging back creates a new
pty under the same path, as a USB adapter re-enumerating would.

The driver's baud rate is visible on the master side (the pty's termios settings). When it does
not match the emulated device's, the emulator garbles what it sends and ignores what it receives,
as a real device on a mismatched line would look.

Emulators are controlled through lines on standard input (fault injection) and report events as
lines on standard output, so that tests in another process (or a user in a terminal) can drive
them: ``garbage 40``, ``unplug 2``, ``silence 1.5``, ``quit``..., answered by lines such as
``ready /tmp/m3/create`` or ``unplugged``.
"""

from __future__ import annotations

import argparse
import contextlib
import errno
import fcntl
import os
import pty
import random
import select
import signal
import sys
import termios
import time
import tty
from collections.abc import Callable

_SPEEDS = {
    getattr(termios, f"B{rate}"): rate
    for rate in (9600, 19200, 38400, 57600, 115200, 230400, 460800, 500000, 576000, 921600, 1000000)
    if hasattr(termios, f"B{rate}")
}


class PtyDevice:
    """A pty whose slave side is published under `link`."""

    def __init__(self, link: str) -> None:
        self.link = os.path.abspath(link)
        self.master: int | None = None
        self._slave: int | None = None

    @property
    def plugged(self) -> bool:
        return self.master is not None

    def plug(self) -> None:
        master, slave = pty.openpty()
        tty.setraw(slave)
        flags = fcntl.fcntl(master, fcntl.F_GETFL)
        fcntl.fcntl(master, fcntl.F_SETFL, flags | os.O_NONBLOCK)
        self.master, self._slave = master, slave
        os.makedirs(os.path.dirname(self.link), exist_ok=True)
        temporary = f"{self.link}.{os.getpid()}.tmp"
        with contextlib.suppress(FileNotFoundError):
            os.unlink(temporary)
        os.symlink(os.ttyname(slave), temporary)
        os.replace(temporary, self.link)

    def unplug(self) -> None:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(self.link)
        for fd in (self.master, self._slave):
            if fd is not None:
                with contextlib.suppress(OSError):
                    os.close(fd)
        self.master = self._slave = None

    def read(self) -> bytes:
        if self.master is None:
            return b""
        try:
            return os.read(self.master, 65536)
        except BlockingIOError:
            return b""
        except OSError as error:
            if error.errno == errno.EIO:
                return b""
            raise

    def write(self, data: bytes) -> None:
        """Write what the line takes; a full buffer (nobody reading) drops the rest, like a UART."""
        if self.master is None or not data:
            return
        with contextlib.suppress(BlockingIOError, OSError):
            os.write(self.master, data)

    def baud(self) -> int | None:
        """The baud rate the driver set on its side of the line."""
        if self.master is None:
            return None
        try:
            speed = termios.tcgetattr(self.master)[5]
        except termios.error:
            return None
        return _SPEEDS.get(speed)


def garble(data: bytes, rng: random.Random) -> bytes:
    """What bytes look like when received at the wrong baud rate: framing noise."""
    return bytes(rng.randrange(256) for _ in range(max(1, len(data) // 2)))


class EmulatorApp:
    """Select loop around a PtyDevice, stdin control lines and periodic work.

    Subclasses implement ``on_bytes`` (data from the driver), ``tick`` (periodic, with the time)
    and ``command`` (a control line not handled here; return False when unknown).
    """

    tick_period = 0.005
    supports_partial = False  # whether `partial` (cut the next message in half) means anything here

    def __init__(self, link: str, baud: int, seed: int = 1) -> None:
        self.device = PtyDevice(link)
        self.baud = baud
        self.rng = random.Random(seed)
        self.silent_until = 0.0
        self.plug_at: float | None = None
        self.running = True
        self._stdin_open = True
        self._baud_warned = False
        self.corrupt_next = 0  # messages still to corrupt (`corrupt N`)
        self.partial_next = False  # cut the next message in half (`partial`)

    # -- output
    def emit(self, line: str) -> None:
        print(line, flush=True)

    def send(self, data: bytes) -> None:
        """Send to the driver (garbled when the driver's baud rate is wrong, nothing when silent)."""
        if time.monotonic() < self.silent_until or not self.device.plugged:
            return
        if not self.baud_matches():
            data = garble(data, self.rng)
        self.device.write(data)

    def baud_matches(self) -> bool:
        if self.baud == 0:  # a USB (CDC-ACM) device: the baud rate setting does not matter
            return True
        driver_baud = self.device.baud()
        matches = driver_baud is None or driver_baud == self.baud
        if not matches and not self._baud_warned:
            self.emit(f"baud_mismatch driver={driver_baud} device={self.baud}")
        self._baud_warned = not matches
        return matches

    def take_corruption(self) -> bool:
        """Whether the message going out now is to be corrupted (one of `corrupt N`)."""
        if not self.corrupt_next:
            return False
        self.corrupt_next -= 1
        return True

    def take_partial(self) -> bool:
        """Whether the message going out now is to be cut in half (`partial`)."""
        taken, self.partial_next = self.partial_next, False
        return taken

    # -- hooks
    def on_bytes(self, data: bytes, now: float) -> None:
        raise NotImplementedError

    def tick(self, now: float) -> None:
        pass

    def command(self, words: list[str], now: float) -> bool:
        return False

    def on_plugged(self) -> None:
        """A new pty: the device powers up again."""

    # -- control
    def _control(self, line: str, now: float) -> None:
        words = line.split()
        if not words:
            return
        verb = words[0]
        try:
            if verb == "quit":
                self.running = False
            elif verb == "garbage":
                count = int(words[1]) if len(words) > 1 else 32
                self.device.write(bytes(self.rng.randrange(256) for _ in range(count)))
                self.emit(f"garbage {count}")
            elif verb == "silence":
                seconds = float(words[1]) if len(words) > 1 else 1.0
                self.silent_until = now + seconds
                self.emit(f"silence {seconds:g}")
            elif verb == "unplug":
                seconds = float(words[1]) if len(words) > 1 else 0.0
                self.device.unplug()
                self.plug_at = now + seconds if seconds > 0 else None
                self.emit(f"unplugged t={time.monotonic():.6f}")
            elif verb == "plug":
                self._plug()
            elif verb == "corrupt":
                self.corrupt_next = int(words[1]) if len(words) > 1 else 1
                self.emit(f"corrupt {self.corrupt_next}")
            elif verb == "partial" and self.supports_partial:
                self.partial_next = True
                self.emit("partial")
            elif not self.command(words, now):
                self.emit(f"error unknown command: {line.strip()}")
        except (IndexError, ValueError) as error:
            self.emit(f"error bad command '{line.strip()}': {error}")

    def _plug(self) -> None:
        if not self.device.plugged:
            self.device.plug()
            self.plug_at = None
            self.on_plugged()
            self.emit(f"ready {self.device.link} t={time.monotonic():.6f}")

    def run(self) -> int:
        signal.signal(signal.SIGTERM, lambda *_: setattr(self, "running", False))
        self._plug()
        stdin_buffer = b""
        try:
            while self.running:
                now = time.monotonic()
                if self.plug_at is not None and now >= self.plug_at:
                    self._plug()
                fds = [fd for fd in (self.device.master,) if fd is not None]
                if self._stdin_open:
                    fds.append(sys.stdin.fileno())
                readable, _, _ = select.select(fds, [], [], self.tick_period)
                now = time.monotonic()
                if self._stdin_open and sys.stdin.fileno() in readable:
                    chunk = os.read(sys.stdin.fileno(), 4096)
                    if not chunk:
                        self._stdin_open = False
                    stdin_buffer += chunk
                    while b"\n" in stdin_buffer:
                        line, stdin_buffer = stdin_buffer.split(b"\n", 1)
                        self._control(line.decode("utf-8", "replace"), now)
                if self.device.master is not None and self.device.master in readable:
                    data = self.device.read()
                    if data and now >= self.silent_until and self.baud_matches():
                        self.on_bytes(data, now)
                self.tick(now)
        except KeyboardInterrupt:
            pass
        finally:
            self.device.unplug()
        return 0


def common_arguments(parser: argparse.ArgumentParser, default_link: str, default_baud: int) -> None:
    parser.add_argument(
        "--port", default=default_link,
        help=f"path under which the emulated device appears (a symlink to the pty; default {default_link})",
    )
    parser.add_argument("--baud", type=int, default=default_baud,
                        help=f"the device's baud rate (default {default_baud}; 0: any, as over USB)")
    parser.add_argument("--seed", type=int, default=1, help="random seed for noise and garbage")


def run_emulator(make: Callable[[argparse.Namespace], EmulatorApp], args: argparse.Namespace) -> int:
    try:
        app = make(args)
    except (OSError, ValueError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    return app.run()
