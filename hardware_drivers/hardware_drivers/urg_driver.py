"""Hokuyo URG driver (SCIP 2.0): connect, read the sensor's parameters, stream scans (no ROS).

Connect: for each candidate baud rate (the configured one, then 19200, 38400, 115200) send QT; a
SCIP 2.0 reply means the sensor is ready; an ``E`` status means SCIP 1.1 (the URG-04LX boots in
it), so send ``SCIP2.0`` and check with QT again. Then PP (model, DMIN/DMAX, ARES, AMIN/AMAX/AFRT,
scan speed), BM (laser on) and MD AMIN..AMAX (continuous 3-character scans).

Every scan's lines are checksum-verified; a scan with a bad line, the wrong number of ranges or a
hardware-fault status is dropped and counted. After ``error_limit`` bad scans in a row, or no scan
for ``scan_timeout``, the driver drops the connection and reconnects (as urg_node does, retrying
every 0.5 s), so a sensor that was unplugged, reset or garbled comes back on its own.

Ranges: raw values below DMIN are the sensor's error codes and become NaN; above DMAX, +inf.
The angle of step s is (s - AFRT) * 2 pi / ARES.
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass

import numpy as np

from hardware_drivers import scip
from hardware_drivers.device_health import EventSink, Level
from hardware_drivers.laser_scan import LaserScanData
from hardware_drivers.scip import ScipError, SensorParameters
from hardware_drivers.serial_link import DeviceNotRespondingError, SerialPort, SupervisedDevice

CANDIDATE_BAUDS = (19200, 38400, 115200)


@dataclass(frozen=True)
class UrgConfig:
    port: str
    baud: int = 115200  # tried first; for a USB URG any value works
    cluster: int = 1  # adjacent steps merged into one range
    skip: int = 0  # scans skipped between two sent (MD scan interval)
    reply_timeout: float = 0.5  # s for a command's reply
    scan_timeout: float = 1.0  # s without a scan before the sensor counts as lost
    error_limit: int = 4  # bad scans in a row before reconnecting
    retry_interval: float = 0.5  # s between reconnect attempts

    def validate(self) -> None:
        problems = []
        if not 1 <= self.cluster <= 99:
            problems.append(f"cluster must be 1..99, got {self.cluster}")
        if not 0 <= self.skip <= 9:
            problems.append(f"skip must be 0..9, got {self.skip}")
        for name in ("reply_timeout", "scan_timeout", "retry_interval"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                problems.append(f"{name} must be positive, got {value}")
        if self.error_limit < 1:
            problems.append(f"error_limit must be at least 1, got {self.error_limit}")
        if self.baud <= 0:
            problems.append(f"baud must be positive, got {self.baud}")
        if problems:
            raise ValueError("; ".join(problems))


class UrgDriver(SupervisedDevice):
    device_name = "Hokuyo URG"

    def __init__(self, config: UrgConfig, on_event: EventSink | None = None) -> None:
        config.validate()
        super().__init__(config.port, config.baud, config.retry_interval, on_event)
        self.config = config
        self.parameters: SensorParameters | None = None
        self._lock = threading.Lock()
        self._scan: LaserScanData | None = None
        self._sequence = 0
        self._splitter = scip.ReplySplitter()
        self._version: dict[str, str] = {}
        self.health.set_value("port", config.port)

    # ------------------------------------------------------------------ public API
    def latest_scan(self) -> tuple[int, LaserScanData | None]:
        with self._lock:
            return self._sequence, self._scan

    # ------------------------------------------------------------------ connect
    def _request(self, port: SerialPort, text: str, timeout: float | None = None) -> scip.Reply | None:
        """Send a command, return its reply (matched by echo), or None on timeout."""
        port.write(scip.command(text))
        deadline = time.monotonic() + (timeout or self.config.reply_timeout)
        echo = text.encode("ascii")
        while (remaining := deadline - time.monotonic()) > 0:
            for block in self._splitter.feed(port.read(timeout=min(remaining, 0.05))):
                try:
                    reply = scip.parse_reply(block)
                except ScipError:
                    continue
                if reply.echo == echo:
                    return reply
        return None

    def _find_protocol(self, port: SerialPort) -> int:
        """Talk SCIP 2.0 with the sensor at some baud rate; returns the rate."""
        bauds = list(dict.fromkeys((self.config.baud, *CANDIDATE_BAUDS)))
        for baud in bauds:
            port.set_baud(baud)
            port.discard_input()
            self._splitter.reset()
            reply = self._request(port, "QT")
            if reply is None:
                continue
            if reply.status == b"00" and reply.status_sum_ok:
                return baud
            # a SCIP 1.1 sensor does not know QT: switch it to SCIP 2.0
            switch = self._request(port, "SCIP2.0")
            if switch is None or not switch.status.startswith(b"0"):
                continue
            self.health.event(Level.OK, f"switched the URG on {self.path} from SCIP 1.1 to SCIP 2.0")
            reply = self._request(port, "QT")
            if reply is not None and reply.status == b"00":
                return baud
        raise DeviceNotRespondingError(
            f"no SCIP reply on {self.path} at {', '.join(str(b) for b in bauds)} baud: "
            "is the URG connected and powered?"
        )

    def _session(self, port: SerialPort) -> None:
        self._splitter = scip.ReplySplitter()
        baud = self._find_protocol(port)
        pp = self._request(port, "PP")
        if pp is None or pp.status != b"00":
            raise DeviceNotRespondingError("the URG did not answer PP (sensor parameters)")
        try:
            parameters = SensorParameters.from_pp(scip.parse_parameters(pp))
        except ScipError as error:
            raise DeviceNotRespondingError(f"bad PP reply: {error}") from None
        self.parameters = parameters
        vv = self._request(port, "VV")
        if vv is not None and vv.status == b"00":
            try:
                self._version = scip.parse_parameters(vv)
            except ScipError:
                self._version = {}
        bm = self._request(port, "BM")
        if bm is None or bm.status not in (b"00", b"02"):
            status = "no reply" if bm is None else f"status {bm.status.decode('ascii', 'replace')}"
            raise DeviceNotRespondingError(f"the URG could not switch its laser on (BM: {status})")
        md_text = (
            f"MD{parameters.amin:04d}{parameters.amax:04d}{self.config.cluster:02d}{self.config.skip:01d}00"
        )
        md = self._request(port, md_text)
        if md is None or md.status != b"00":
            status = "no reply" if md is None else f"status {md.status.decode('ascii', 'replace')}"
            raise DeviceNotRespondingError(f"the URG refused continuous scanning ({md_text}: {status})")
        for key, value in (("model", parameters.model), ("baud", baud),
                           ("firmware", self._version.get("FIRM", "?")),
                           ("steps", f"{parameters.amin}..{parameters.amax} of {parameters.ares}")):
            self.health.set_value(key, value)
        self._connected(
            f"connected to the {self.device_name} on {self.path} ({parameters.model.split('(')[0]}, "
            f"{baud} baud, steps {parameters.amin}..{parameters.amax}, {parameters.scan_rpm} rpm)"
        )
        self._stream(port, parameters, md_text.encode("ascii"))
        try:
            port.write(scip.command("QT"))  # leave the laser off when we stop
        except Exception:
            pass

    # ------------------------------------------------------------------ scans
    def _stream(self, port: SerialPort, parameters: SensorParameters, md_echo: bytes) -> None:
        expected = len(range(parameters.amin, parameters.amax + 1, self.config.cluster))
        bad_in_a_row = 0
        last_scan = time.monotonic()
        last_fault = ""
        while not self._stopping.is_set():
            blocks = self._splitter.feed(port.read(timeout=0.05))
            now = time.monotonic()
            for block in blocks:
                problem = self._handle_block(block, parameters, md_echo, expected, now)
                if problem is None:
                    bad_in_a_row = 0
                    last_scan = now
                    if last_fault:
                        self.health.event(Level.OK, "URG scans valid again", set_state=True)
                        last_fault = ""
                elif problem:  # "" means a block that is no scan (an acknowledgement)
                    bad_in_a_row += 1
                    if problem != last_fault:
                        self.health.event(Level.WARN if "hardware" not in problem else Level.ERROR,
                                          f"URG scan dropped: {problem}", set_state=True)
                        last_fault = problem
                    if bad_in_a_row >= self.config.error_limit:
                        raise DeviceNotRespondingError(f"{bad_in_a_row} bad scans in a row (last: {problem})")
            if now - last_scan > self.config.scan_timeout:
                raise DeviceNotRespondingError(f"no scan for {self.config.scan_timeout:g} s")
            self.health.set_counter("dropped_bytes", self._splitter.dropped_bytes)

    def _handle_block(self, block: bytes, parameters: SensorParameters, md_echo: bytes, expected: int,
                      now: float) -> str | None:
        """None for a valid scan (published), "" for a harmless block, else why the block was dropped."""
        try:
            reply = scip.parse_reply(block)
        except ScipError as error:
            self.health.count("corrupt_scans")
            return f"unreadable reply ({error})"
        if reply.echo[:13] != md_echo[:13]:
            self.health.count("corrupt_scans")
            return "garbage on the line (unexpected echo)"
        if not reply.status_sum_ok:
            self.health.count("corrupt_scans")
            return "status checksum mismatch"
        if reply.status == b"00":
            return ""
        if reply.status != b"99":
            self.health.count("fault_scans")
            code = reply.status.decode("ascii", "replace")
            kind = "hardware fault" if code.isdigit() and 50 <= int(code) <= 97 else "error"
            return f"URG reports {kind} (status {code})"
        try:
            data = scip.parse_scan(reply, 3)
        except ScipError as error:
            self.health.count("corrupt_scans")
            return f"checksum error ({error})"
        if len(data.ranges) != expected:
            self.health.count("corrupt_scans")
            return f"{len(data.ranges)} ranges instead of {expected}"
        raw = np.asarray(data.ranges, dtype=float)
        ranges = np.where(raw < parameters.dmin, np.nan, raw / 1000.0)
        ranges = np.where(raw > parameters.dmax, np.inf, ranges)
        step_time = parameters.scan_time / parameters.ares
        scan = LaserScanData(
            stamp=now - parameters.scan_time,  # the scan started about one revolution before it arrived
            angle_min=parameters.step_angle(parameters.amin + (self.config.cluster - 1) / 2.0),
            angle_increment=parameters.angle_increment * self.config.cluster,
            ranges=ranges,
            range_min=parameters.dmin / 1000.0,
            range_max=parameters.dmax / 1000.0,
            time_increment=step_time * self.config.cluster,
            scan_time=parameters.scan_time * (self.config.skip + 1),
        )
        with self._lock:
            self._scan = scan
            self._sequence += 1
        self.health.count("scans")
        return None

    def _on_disconnect(self) -> None:
        self._splitter = scip.ReplySplitter()
