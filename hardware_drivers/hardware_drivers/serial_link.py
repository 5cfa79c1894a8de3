"""Serial port ownership and the reconnect loop shared by the three device drivers (no ROS).

:class:`SerialPort` wraps pyserial: it opens a device path (``/dev/ttyUSB0`` or a pseudo-terminal
path, exactly alike), reads with timeouts and turns every way a port can fail (missing path, busy,
unplugged mid-run, I/O error) into :class:`DeviceUnavailableError` with a one-line reason.

:class:`SupervisedDevice` runs a driver's protocol session in a thread and keeps it alive: when
the port is missing, the device stops answering or disappears, it reports once, closes the port and
tries again at a fixed interval until the device is back (as ``urg_node`` does, every 0.5 s).
"""

from __future__ import annotations

import os
import select
import termios
import threading
import time

import serial

from hardware_drivers.device_health import DeviceHealth, EventSink, Level


class DeviceUnavailableError(Exception):
    """The port cannot be used: missing, busy, unplugged, I/O error."""


class DeviceNotRespondingError(Exception):
    """The device does not answer as its protocol says, after bounded retries."""


class SerialPort:
    """One open serial device path, with timeouts and one-line failure reasons."""

    def __init__(self, path: str, baud: int, read_timeout: float = 0.02, write_timeout: float = 0.5) -> None:
        self.path = path
        self.baud = baud
        self.read_timeout = read_timeout
        self.write_timeout = write_timeout
        self._serial: serial.Serial | None = None
        self._write_lock = threading.Lock()

    def open(self) -> None:
        if not os.path.exists(self.path):
            raise DeviceUnavailableError(f"port {self.path} does not exist (device unplugged or off?)")
        try:
            self._serial = serial.Serial(
                self.path, self.baud, timeout=self.read_timeout, write_timeout=self.write_timeout,
                exclusive=True,
            )
        except (serial.SerialException, OSError, ValueError) as error:
            raise DeviceUnavailableError(f"cannot open {self.path}: {_reason(error)}") from None

    @property
    def is_open(self) -> bool:
        return self._serial is not None and self._serial.is_open

    def close(self) -> None:
        if self._serial is not None:
            try:
                self._serial.close()
            except (serial.SerialException, OSError):
                pass  # closing a port whose device vanished can fail; it is closed either way
            self._serial = None

    def set_baud(self, baud: int) -> None:
        self.baud = baud
        if self._serial is not None:
            try:
                self._serial.baudrate = baud
            except (serial.SerialException, OSError, ValueError, termios.error) as error:
                reason = _reason(error)
                raise DeviceUnavailableError(f"cannot set {baud} baud on {self.path}: {reason}") from None

    def _port(self) -> serial.Serial:
        if self._serial is None:
            raise DeviceUnavailableError(f"port {self.path} is not open")
        return self._serial

    def read(self, timeout: float | None = None) -> bytes:
        """What has arrived, waiting up to `timeout` (default: the read timeout) for the first byte."""
        port = self._port()
        wait = self.read_timeout if timeout is None else max(0.0, timeout)
        try:
            readable, _, _ = select.select([port.fileno()], [], [], wait)
            if not readable:
                return b""
            # readable with nothing waiting is end-of-file: pyserial's read then raises
            return port.read(max(1, port.in_waiting))
        except (serial.SerialException, OSError, TypeError, ValueError, termios.error) as error:
            # TypeError/ValueError: pyserial or select on a descriptor closed under them
            raise DeviceUnavailableError(f"device on {self.path} disconnected ({_reason(error)})") from None

    def write(self, data: bytes) -> None:
        port = self._port()
        with self._write_lock:
            try:
                port.write(data)
            except serial.SerialTimeoutException:
                raise DeviceNotRespondingError(
                    f"write to {self.path} timed out (device not reading?)") from None
            except (serial.SerialException, OSError, TypeError, termios.error) as error:
                reason = _reason(error)
                raise DeviceUnavailableError(f"device on {self.path} disconnected ({reason})") from None

    def discard_input(self) -> None:
        try:
            self._port().reset_input_buffer()
        except (serial.SerialException, OSError, TypeError, termios.error) as error:
            raise DeviceUnavailableError(f"device on {self.path} disconnected ({_reason(error)})") from None


def _reason(error: BaseException) -> str:
    text = " ".join((str(error).strip() or type(error).__name__).split())
    if "returned no data" in text:  # pyserial's wording for end-of-file on a vanished device
        return "end of file"
    return text


class SupervisedDevice:
    """A device session in its own thread, reconnected forever at a fixed interval.

    Subclasses implement :meth:`_session`: the handshake, then the work loop until
    ``self._stopping`` is set. It raises :class:`DeviceUnavailableError` or :class:`DeviceNotRespondingError`
    when the device is gone or silent; it calls :meth:`_connected` once the handshake succeeded.
    """

    device_name = "device"

    def __init__(self, path: str, baud: int, retry_interval: float = 0.5,
                 on_event: EventSink | None = None) -> None:
        self.path = path
        self.baud = baud
        self.retry_interval = retry_interval
        self.health = DeviceHealth(on_event)
        self.health.set_value("connected", "false")
        self._stopping = threading.Event()
        self._thread: threading.Thread | None = None
        self._connected_flag = threading.Event()
        self.last_connect_time: float | None = None  # time.monotonic() of the last handshake
        self.port: SerialPort | None = None

    # -- lifecycle
    def start(self) -> None:
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name=self.device_name, daemon=True)
            self._thread.start()

    def stop(self) -> None:
        self._stopping.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
            self._thread = None

    @property
    def connected(self) -> bool:
        return self._connected_flag.is_set()

    def wait_connected(self, timeout: float) -> bool:
        return self._connected_flag.wait(timeout)

    # -- for subclasses
    def _make_port(self) -> SerialPort:
        return SerialPort(self.path, self.baud)

    def _session(self, port: SerialPort) -> None:
        raise NotImplementedError

    def _connected(self, message: str) -> None:
        self.last_connect_time = time.monotonic()
        self.health.count("connects")
        self.health.set_value("connected", "true")
        self._connected_flag.set()
        self.health.event(Level.OK, message, set_state=True)

    def _on_disconnect(self) -> None:
        """Called after a session ended (device lost or stopping): drop per-session state."""

    # -- the loop
    def _run(self) -> None:
        last_reason = ""
        while not self._stopping.is_set():
            port = self._make_port()
            self.port = port
            was_connected = False
            try:
                port.open()
                self._session(port)
            except (DeviceUnavailableError, DeviceNotRespondingError) as error:
                was_connected = self._connected_flag.is_set()
                reason = str(error)
                if was_connected:
                    self.health.count("disconnects")
                    self.health.event(
                        Level.ERROR,
                        f"{self.device_name} lost: {reason}; reconnecting every {self.retry_interval:g} s",
                        set_state=True,
                    )
                elif reason != last_reason:
                    self.health.event(
                        Level.ERROR,
                        f"{self.device_name}: {reason}; retrying every {self.retry_interval:g} s",
                        set_state=True,
                    )
                else:
                    self.health.set_state(Level.ERROR, reason)
                last_reason = reason
                self.health.count("connect_failures" if not was_connected else "sessions_lost")
            except Exception as error:  # a driver bug must not kill the reconnect loop silently
                was_connected = self._connected_flag.is_set()
                self.health.count("internal_errors")
                self.health.event(
                    Level.ERROR, f"{self.device_name}: internal error {type(error).__name__}: {error}; "
                    "restarting the session", set_state=True,
                )
            finally:
                self._connected_flag.clear()
                self.health.set_value("connected", "false")
                port.close()
                self._on_disconnect()
            if was_connected:
                last_reason = ""
            self._stopping.wait(self.retry_interval)
