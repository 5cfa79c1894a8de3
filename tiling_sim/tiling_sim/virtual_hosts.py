"""Virtual hosts on one machine: each its own network stack, joined by a shaped "air" like a busy WiFi.

A distributed system that has only ever run on one host may rely on that without anyone noticing
(loopback, shared memory, one clock of message arrival). This module gives each participant a host
of its own, built from Linux network namespaces, so that everything it says to the others crosses
a link that can lose, throttle and cut its packets. It knows nothing about ROS beyond the few
environment variables that keep ROS 2 / Fast DDS on that link (`host_environment`).

Layout (one `VirtualHosts`, i.e. one run)::

    host "robot1" (netns, lo + eth0 10.213.0.1) ──veth── p1 ┐
    host "robot2" (netns, lo + eth0 10.213.0.2) ──veth── p2 ├─ bridge "air" in the hub netns
    host "base"   (netns, lo + eth0 10.213.0.3) ──veth── p3 ┤   + nftables table "air" (loss, outages)
    host "far"    (netns, lo + eth0 10.213.0.4) ─TAP═delay line═TAP─ p4 ┘

Design choices, and why:

- **Namespaces are held by processes, not by names.** Each namespace (every host, and the hub) is
  created by a small keeper process (`unshare --net --uts`, then it waits for end-of-file on a pipe
  whose other end only this object holds). Nothing is bind-mounted under /run/netns, so the kernel
  frees a namespace, with its interfaces, qdiscs and nftables tables, as soon as no process is left
  in it. When the owner exits in any way, even by SIGKILL, the pipe closes, the keepers exit, and
  everything goes away once the processes started inside have exited (a process runner that
  gives them PR_SET_PDEATHSIG, as tiling_sim.process_group does, sees to that). There is nothing
  to clean up after a killed run, and parallel runs can never collide: unnamed namespaces have no
  names to collide on, and every run's interfaces (`eth0`, `air`, `p1`...) live inside its own
  namespaces. (Hence no `remove_leftovers`: there can be none.) `ip netns list` never shows these hosts; look at one
  with `nsenter --net=/proc/PID/ns/net --uts=/proc/PID/ns/uts` (PID: `VirtualHost.keeper_pid`).
- **The bridge lives in a hub namespace of its own, not in the root namespace.** The machine's own
  firewall (Docker sets FORWARD to DROP and loads br_netfilter), routes and interfaces cannot touch
  it; nothing of a run is visible in the root namespace; and the hub is the natural place for the
  "air": all loss, outage and counting rules sit in one nftables table there, and hosts carry no
  rules of their own (a host's own loopback traffic, e.g. multicast looped back to itself, is never
  shaped). The root namespace has no address on the bridge: a process that must take part (say an
  in-process observer) moves its thread into a host with `enter()`.
- **Shaping.** Loss: `numgen random mod 10000 < p*100` drop rules in the bridge family, once per
  frame on the way in from a host (uplink, prerouting hook) and once per frame and receiver on the
  way out to a host (downlink, postrouting hook). A packet between two shaped hosts crosses two
  links, station → access point → station, as in infrastructure-mode WiFi, so its loss is
  1 - (1 - p)^2; leave the base station unshaped to get p end to end. Rate: `tc tbf` on both ends
  of the host's veth (host egress on `eth0`, host ingress on its hub port), each with its own
  bucket: the medium is not shared between hosts, which real WiFi is. Outage: a frame drop for the
  host's port in both directions (an nftables set of ports that are out): the host keeps its
  carrier, as a robot out of range keeps its interface up, and no process sees an error.
  Delay: this kernel cannot hold packets for a time (no netem; no fq or etf, which would honour a
  departure time set by BPF; no plug qdisc; no nft `queue`), and tbf's `latency` is a queue limit,
  not a delay. So a link with `delay_ms` is not a veth but two TAP devices (the host's `eth0` and
  its bridge port) with a delay line between them: a process of its own that writes every frame to
  the other side `delay_ms` after reading it, in order (niced -10, as the air must keep time on a
  busy machine). It is a true delay, with the jitter of a user-space process: on a loaded 2-core
  machine, 50 ms each way gave a round trip of 100.5 ms median, ~110 ms p95, a rare 180 ms; it
  carries at most ~130 Mbit/s and costs CPU per frame. Links without delay stay veths (no cost).
- **ROS 2 discovery: multicast SPDP on the bridge** (`ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET`, the
  Jazzy default), not a Fast DDS discovery server. Multicast is how ROS 2 discovers on a real lab
  WiFi; it needs no extra process, and no host is a single point of failure (a discovery server
  would sit on one host, and every robot whose link to it drops would lose discovery of anyone
  new). The bridge has multicast snooping off, so it floods multicast to every port like a radio,
  and every host routes 224.0.0.0/4 to `eth0`.
- **Shared memory never carries data between hosts.** Namespaces share /dev/shm, and Fast DDS uses
  its SHM transport (and data-sharing) with peers it believes to be on the same machine. Fast DDS
  2.14 decides that from the host id in the GUID prefix, a 16-bit hash of the IPv4 addresses it
  sees; our hosts differ in address, so today they would look like different machines, but a hash
  collision (1 in 65536 per pair) or a later Fast DDS that uses the machine id would change that
  silently. `host_environment` makes it certain: `FASTDDS_BUILTIN_TRANSPORTS=UDPv4` (no SHM
  transport at all), no XML profiles that could bring it back, and `RMW_FASTRTPS_USE_QOS_FROM_XML`
  off so that rmw_fastrtps keeps data-sharing off for every endpoint. Processes on one host then
  talk over UDP on its loopback, and to other hosts over `eth0` (tests/sim/test_virtual_hosts.py
  shows the bytes crossing the link, and nothing arriving while the link is out).

Needs root, `ip`/`tc` (iproute2), `nft` (nftables), `unshare`/`nsenter` (util-linux); without them
`VirtualHosts()` raises `VirtualHostsUnavailableError` with one line saying what is missing.
"""

from __future__ import annotations

import ctypes
import fcntl
import heapq
import ipaddress
import itertools
import json
import os
import select
import shutil
import struct
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import TypeVar

T = TypeVar("T")

BRIDGE = "air"  # the bridge in the hub namespace, and the nftables table that shapes it
HOST_INTERFACE = "eth0"  # a host's end of its veth
MULTICAST = "224.0.0.0/4"

# Fast DDS discovery and transports for a process on a virtual host; see the module docstring.
ROS_HOST_VARIABLES = {
    "ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET",
    "FASTDDS_BUILTIN_TRANSPORTS": "UDPv4",
    "RMW_FASTRTPS_USE_QOS_FROM_XML": "0",
    "SKIP_DEFAULT_XML": "1",  # ignore a DEFAULT_FASTRTPS_PROFILES.xml in the working directory
}
# Variables that would override the above: localhost-only discovery, fixed peers, XML profiles
# (which may re-enable the SHM transport or data-sharing).
ROS_VARIABLES_REMOVED = (
    "ROS_LOCALHOST_ONLY",
    "ROS_STATIC_PEERS",
    "FASTRTPS_DEFAULT_PROFILES_FILE",
    "FASTDDS_DEFAULT_PROFILES_FILE",
)

# The commands this module runs, and where Debian has them.
REQUIRED_COMMANDS = {
    "ip": "iproute2",
    "tc": "iproute2",
    "nft": "nftables",
    "unshare": "util-linux",
    "nsenter": "util-linux",
}

# tbf sizing: the bucket lets a few frames through back to back (and must hold one full frame); the
# queue holds a few of Fast DDS's largest datagrams (64 KiB, sent as ~45 IP fragments: a queue
# smaller than that would drop a fragment of every large sample, i.e. the whole sample, forever)
# or a quarter of a second of traffic, whichever is more, as an access point's buffer would.
_FRAME_BYTES = 1514
_LARGEST_DATAGRAM = 65536
_QUEUE_SECONDS = 0.25

_CLONE_NEWNET = 0x40000000
_TUNSETIFF, _IFF_TAP, _IFF_NO_PI = 0x400454CA, 0x0002, 0x1000  # <linux/if_tun.h>
_MAX_DELAY_MS = 10_000.0
_DELAY_LINE_FRAMES = 20_000  # frames a delay line holds at most (a queue limit, as a device has)


class VirtualHostsError(RuntimeError):
    """Setting up or changing the virtual network failed; the message is one line naming the command."""


class VirtualHostsUnavailableError(VirtualHostsError):
    """This machine or user cannot make virtual hosts; the message is one line saying why."""


@dataclass(frozen=True)
class LinkShape:
    """How a host's link to the others behaves, in each direction."""

    loss_percent: float = 0.0  # share of frames dropped at random, 0 <= loss < 100
    rate_mbit: float | None = None  # token-bucket rate limit in Mbit/s, None: as fast as the machine
    delay_ms: float = 0.0  # one-way delay added by a user-space delay line; 0: a plain veth

    def __post_init__(self) -> None:
        if not 0.0 <= self.loss_percent < 100.0:
            raise ValueError(f"link loss must be at least 0 and below 100 percent, not {self.loss_percent}")
        if self.rate_mbit is not None and not self.rate_mbit > 0.0:
            raise ValueError(f"link rate must be above 0 Mbit/s, not {self.rate_mbit}")
        if not 0.0 <= self.delay_ms <= _MAX_DELAY_MS:
            raise ValueError(f"link delay must be between 0 and {_MAX_DELAY_MS:g} ms, not {self.delay_ms}")

    def __str__(self) -> str:
        loss = f"{self.loss_percent:g}% loss" if self.loss_percent else "no loss"
        rate = f"{self.rate_mbit:g} Mbit/s" if self.rate_mbit is not None else "no rate limit"
        delay = f", {self.delay_ms:g} ms delay" if self.delay_ms else ""
        return f"{loss}, {rate}{delay}"


@dataclass(frozen=True)
class VirtualHost:
    name: str
    address: str  # its IPv4 address on the bridge
    port: str  # its link's end on the bridge, in the hub namespace
    link: LinkShape
    keeper_pid: int  # the process that holds its namespaces

    @property
    def net_namespace(self) -> str:
        return f"/proc/{self.keeper_pid}/ns/net"

    @property
    def uts_namespace(self) -> str:
        return f"/proc/{self.keeper_pid}/ns/uts"


@dataclass(frozen=True)
class LinkCounters:
    """What went over one host's link since it was created (frames, and their bytes)."""

    sent_packets: int  # frames the host put on its link (after its own rate limit)
    sent_bytes: int
    received_packets: int  # frames that reached the host
    received_bytes: int
    lost_sent: int  # frames from the host dropped by the random-loss rule
    lost_received: int  # frames to the host dropped by the random-loss rule
    outage_dropped: int  # frames dropped in either direction while the link was out
    queue_dropped: int  # frames the rate limiter's queues dropped, at either end


def check_available() -> None:
    """Raise `VirtualHostsUnavailableError` (one line) unless this process can make virtual hosts."""
    if os.geteuid() != 0:
        raise VirtualHostsUnavailableError(
            "virtual hosts need root (network namespaces, bridges, nftables): run as root"
        )
    for command, package in REQUIRED_COMMANDS.items():
        if shutil.which(command) is None:
            raise VirtualHostsUnavailableError(
                f"virtual hosts need the '{command}' command: install the Debian package {package} "
                f"(apt-get install -y {package})"
            )


def _run(argv: Sequence[str], what: str, stdin: str | None = None) -> str:
    """Run a set-up command; its output, or `VirtualHostsError` naming what failed and why."""
    try:
        result = subprocess.run(list(argv), input=stdin, capture_output=True, text=True, timeout=30)
    except (OSError, subprocess.TimeoutExpired) as error:
        raise VirtualHostsError(f"could not {what}: {' '.join(argv)}: {error}") from None
    if result.returncode != 0:
        raise VirtualHostsError(f"could not {what}: {' '.join(argv)}: {_reason(result)}")
    return result.stdout


def _reason(result: subprocess.CompletedProcess[str]) -> str:
    """The line of a failed command's output that says what went wrong (nft adds the rule and a
    caret line after its "Error:" line; the others print one line)."""
    lines = [line.strip() for line in (result.stderr + result.stdout).splitlines() if line.strip()]
    errors = [line for line in lines if line.startswith("Error")]
    return (errors or lines or [f"exit code {result.returncode}"])[0]


def _in_namespace(keeper_pid: int, argv: Sequence[str]) -> list[str]:
    """`argv` run in the network and UTS namespaces `keeper_pid` holds (nsenter execs: same pid)."""
    return ["nsenter", f"--net=/proc/{keeper_pid}/ns/net", f"--uts=/proc/{keeper_pid}/ns/uts", "--", *argv]


def _start_keeper(label: str, hostname: str) -> subprocess.Popen[str]:
    """A process in fresh network and UTS namespaces that lives until its stdin reaches EOF.

    Inside, before saying it is ready: IPv6 off (no router solicitations or multicast listener
    reports on the link; everything here is IPv4) and the hostname set to the host's name."""
    script = (
        "echo 1 > /proc/sys/net/ipv6/conf/default/disable_ipv6 && "
        "echo 1 > /proc/sys/net/ipv6/conf/all/disable_ipv6 && "
        f"echo '{hostname}' > /proc/sys/kernel/hostname && "
        "echo ready && read -r _line; exit 0"
    )
    try:
        keeper = subprocess.Popen(
            ["unshare", "--net", "--uts", "--", "sh", "-c", script, label],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            start_new_session=True,  # a Ctrl-C at the terminal is for the owner; it tears down in order
        )
    except OSError as error:
        raise VirtualHostsError(f"could not start a namespace keeper ({label}): {error}") from None
    assert keeper.stdout is not None
    if keeper.stdout.readline().strip() != "ready":
        keeper.wait()
        reason = keeper.stderr.read().strip() if keeper.stderr else ""
        raise VirtualHostsError(f"could not create network namespaces ({label}): {reason or 'the keeper exited'}")
    return keeper


def _stop_keeper(keeper: subprocess.Popen[str]) -> None:
    for stream in (keeper.stdin, keeper.stdout, keeper.stderr):
        if stream is not None:
            stream.close()  # stdin's end-of-file is what tells the keeper to exit
    try:
        keeper.wait(timeout=5)
    except subprocess.TimeoutExpired:
        keeper.kill()
        keeper.wait()


def _setns(path: str) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        if ctypes.CDLL(None, use_errno=True).setns(fd, _CLONE_NEWNET) != 0:
            raise VirtualHostsError(f"could not enter the network namespace {path}: {os.strerror(ctypes.get_errno())}")
    finally:
        os.close(fd)


def _inside(net_namespace: str, make: Callable[[], T]) -> T:
    """`make()` called on a short-lived thread moved into `net_namespace` (this thread stays put).
    What it creates there (a socket, a TAP device) stays there when the thread ends."""
    made: list[T] = []
    failed: list[BaseException] = []

    def run() -> None:
        try:
            _setns(net_namespace)
            made.append(make())
        except BaseException as error:
            failed.append(error)

    thread = threading.Thread(target=run, name="virtual-hosts-setns")
    thread.start()
    thread.join()
    if failed:
        raise failed[0]
    return made[0]


def _open_tap(net_namespace: str, name: str) -> int:
    """A TAP device called `name` in `net_namespace`; it exists as long as the returned fd is open."""

    def make() -> int:
        fd = os.open("/dev/net/tun", os.O_RDWR)
        try:
            fcntl.ioctl(fd, _TUNSETIFF, struct.pack("16sH", name.encode(), _IFF_TAP | _IFF_NO_PI))
        except OSError:
            os.close(fd)
            raise
        return fd

    try:
        return _inside(net_namespace, make)
    except OSError as error:
        raise VirtualHostsError(f"could not create the TAP device {name} for a delay line: {error}") from None


def _start_delay_line(label: str, delay_ms: float, host_tap: int, port_tap: int) -> subprocess.Popen[str]:
    """A process carrying frames between two TAP devices `delay_ms` late (see `_delay_line`); it owns
    both devices (this process closes its copies) and exits at end-of-file on its stdin."""
    argv = [sys.executable, os.path.abspath(__file__), "delay-line", str(delay_ms), str(host_tap), str(port_tap)]
    try:
        relay = subprocess.Popen(
            [*argv, label],
            stdin=subprocess.PIPE,
            pass_fds=(host_tap, port_tap),
            text=True,
            start_new_session=True,
        )
    except OSError as error:
        raise VirtualHostsError(f"could not start the delay line ({label}): {error}") from None
    finally:
        os.close(host_tap)
        os.close(port_tap)
    return relay


def _delay_line(delay_ms: float, host_tap: int, port_tap: int) -> None:
    """Forward every frame read from one TAP device to the other, `delay_ms` after it was read, in
    order; return at end-of-file on stdin (the owner closed the pipe, or died)."""
    if os.geteuid() == 0:
        os.nice(-10)  # the air must keep time when the machine is busy
    delay = delay_ms / 1000.0
    other = {host_tap: port_tap, port_tap: host_tap}
    owner = sys.stdin.fileno()
    due: list[tuple[float, int, int, bytes]] = []  # (time to write, sequence, device, frame)
    sequence = itertools.count()
    while True:
        wait = max(0.0, due[0][0] - time.monotonic()) if due else None
        readable, _, _ = select.select([host_tap, port_tap, owner], [], [], wait)
        if owner in readable and not os.read(owner, 1):
            return
        arrived = time.monotonic()
        for device in readable:
            if device == owner:
                continue
            try:
                frame = os.read(device, 65536)
            except OSError:
                continue  # the device went down between select and read
            if len(due) < _DELAY_LINE_FRAMES:
                heapq.heappush(due, (arrived + delay, next(sequence), other[device], frame))
        while due and due[0][0] <= time.monotonic():
            _, _, device, frame = heapq.heappop(due)
            try:
                os.write(device, frame)
            except OSError:
                pass  # the device is down (link being removed): the frame is lost, as on a wire


def _tbf(device: str, rate_mbit: float) -> list[str]:
    """`tc` arguments for a token bucket of `rate_mbit` on `device`, sized as explained above."""
    bytes_per_second = rate_mbit * 1e6 / 8
    burst = max(4 * _FRAME_BYTES, int(bytes_per_second * 0.01))
    limit = max(3 * _LARGEST_DATAGRAM + burst, int(bytes_per_second * _QUEUE_SECONDS))
    rate_kbit = max(1, round(rate_mbit * 1000))
    return ["tc", "qdisc", "replace", "dev", device, "root", "tbf",
            "rate", f"{rate_kbit}kbit", "burst", str(burst), "limit", str(limit)]  # fmt: skip


def _loss_rule(loss_percent: float, counter: str) -> str:
    """An nft rule dropping `loss_percent` of frames at random (to 0.01 %), counted in `counter`."""
    threshold = round(loss_percent * 100)
    return f'numgen random mod 10000 < {threshold} counter name "{counter}" drop;' if threshold else ""


class VirtualHosts:
    """The hosts of one run, on one bridge; a context manager that removes them all at exit."""

    def __init__(self, run_id: str = "", subnet: str = "10.213.0.0/24") -> None:
        check_available()
        self.run_id = run_id or str(os.getpid())
        self.network = ipaddress.ip_network(subnet)
        self.hosts: dict[str, VirtualHost] = {}
        self._keepers: list[subprocess.Popen[str]] = []
        self._relays: list[subprocess.Popen[str]] = []  # delay lines
        self._out: set[str] = set()  # ports whose link is cut
        self._free_addresses = self.network.hosts()
        self._port_numbers = itertools.count(1)  # never reused, even after a host that failed half-way
        try:
            self._hub = self._keep(_start_keeper(self._label("hub"), "hub"))
            self._make_air()
        except BaseException:
            self.close()
            raise

    def _label(self, name: str) -> str:
        """What `ps` shows for the keeper of `name` (and what `keeper_processes` looks for)."""
        return f"tiling-virtual-hosts:{self.run_id}:{name}"

    # --- building -----------------------------------------------------------------------------

    def _make_air(self) -> None:
        """The bridge in the hub and the nftables table where the hosts' ports are shaped."""
        self._hub_run(["ip", "link", "add", BRIDGE, "type", "bridge", "stp_state", "0", "mcast_snooping", "0"],
                      "create the bridge")  # fmt: skip
        self._hub_run(["ip", "link", "set", BRIDGE, "up"], "bring the bridge up")
        ruleset = f"""
            table bridge {BRIDGE} {{
                set out {{ type ifname; comment "ports whose link is out"; }}
                chain uplink {{ type filter hook prerouting priority 0; policy accept; }}
                chain downlink {{ type filter hook postrouting priority 0; policy accept; }}
            }}
        """
        self._hub_run(["nft", "-f", "-"], "create the nftables table (bridge family)", ruleset)

    def _keep(self, keeper: subprocess.Popen[str]) -> int:
        self._keepers.append(keeper)
        return keeper.pid

    def _hub_run(self, argv: Sequence[str], what: str, stdin: str | None = None) -> str:
        return _run(_in_namespace(self._hub, argv), what, stdin)

    def add_host(self, name: str, link: LinkShape | None = None) -> VirtualHost:
        """A new host called `name` on the bridge, its link shaped by `link` (default: perfect)."""
        if name in self.hosts:
            raise ValueError(f"there is already a virtual host called {name}")
        if not name or not all(c.isalnum() or c in "-_." for c in name):
            raise ValueError(f"a virtual host name needs letters, digits, '-', '_' or '.': {name!r}")
        link = link or LinkShape()
        try:
            address = str(next(self._free_addresses))
        except StopIteration:
            raise VirtualHostsError(f"the subnet {self.network} has no address left for {name}") from None
        keeper = self._keep(_start_keeper(self._label(name), name))
        host = VirtualHost(name, address, f"p{next(self._port_numbers)}", link, keeper)
        self._connect(host)
        self._shape(host)
        self.hosts[name] = host
        return host

    def _connect(self, host: VirtualHost) -> None:
        """A link from the host's `eth0` to a bridge port; its address; loopback; multicast route.

        The link is a veth pair, or, for a delay, two TAP devices with a delay line between them."""
        if host.link.delay_ms:
            host_tap = _open_tap(host.net_namespace, HOST_INTERFACE)
            port_tap = _open_tap(f"/proc/{self._hub}/ns/net", host.port)
            self._relays.append(_start_delay_line(self._label(host.name), host.link.delay_ms, host_tap, port_tap))
        else:
            self._hub_run(["ip", "link", "add", host.port, "type", "veth", "peer", "name", HOST_INTERFACE,
                           "netns", str(host.keeper_pid)], f"create the link of {host.name}")  # fmt: skip
        self._hub_run(["ip", "link", "set", host.port, "alias", host.name, "master", BRIDGE, "up"],
                      f"attach {host.name} to the bridge")  # fmt: skip
        prefix = f"{host.address}/{self.network.prefixlen}"
        for argv in (
            ["ip", "link", "set", "lo", "up"],
            ["ip", "address", "add", prefix, "dev", HOST_INTERFACE],
            ["ip", "link", "set", HOST_INTERFACE, "up"],
            # DDS discovery sends to 239.255.0.1; a host has no default route to carry it
            ["ip", "route", "add", MULTICAST, "dev", HOST_INTERFACE],
        ):
            _run(_in_namespace(host.keeper_pid, argv), f"configure {host.name}")

    def _shape(self, host: VirtualHost) -> None:
        """Counters and loss rules for the host's port in the hub's table; tbf on both veth ends."""
        port = host.port
        counters = "; ".join(f"counter {port}_{kind} {{ }}" for kind in ("lost_sent", "lost_received", "outage"))
        sent_loss = _loss_rule(host.link.loss_percent, f"{port}_lost_sent")
        received_loss = _loss_rule(host.link.loss_percent, f"{port}_lost_received")
        ruleset = f"""
            table bridge {BRIDGE} {{
                {counters}
                chain {port}_sent {{ iifname @out counter name "{port}_outage" drop; {sent_loss} }}
                chain {port}_received {{ oifname @out counter name "{port}_outage" drop; {received_loss} }}
                chain uplink {{ iifname "{port}" jump {port}_sent; }}
                chain downlink {{ oifname "{port}" jump {port}_received; }}
            }}
        """
        self._hub_run(["nft", "-f", "-"], f"add the loss rules of {host.name}", ruleset)
        if host.link.rate_mbit is not None:
            _run(_in_namespace(host.keeper_pid, _tbf(HOST_INTERFACE, host.link.rate_mbit)),
                 f"limit the rate of {host.name}'s sending (tbf qdisc)")  # fmt: skip
            self._hub_run(_tbf(port, host.link.rate_mbit), f"limit the rate of {host.name}'s receiving (tbf qdisc)")

    @property
    def keeper_pids(self) -> list[int]:
        """The processes holding this run's namespaces: the hub's first, then one per host."""
        return [keeper.pid for keeper in self._keepers]

    @property
    def delay_line_pids(self) -> list[int]:
        return [relay.pid for relay in self._relays]

    # --- using ----------------------------------------------------------------------------------

    def host(self, host: VirtualHost | str) -> VirtualHost:
        name = host.name if isinstance(host, VirtualHost) else host
        if name not in self.hosts:
            raise KeyError(f"no virtual host called {name}")
        return self.hosts[name]

    def command(self, host: VirtualHost | str, argv: Sequence[str]) -> list[str]:
        """`argv` to run as a process on `host`. The program replaces nsenter (same pid), so
        signals sent to the pid reach it, and a PR_SET_PDEATHSIG set before exec still holds."""
        return _in_namespace(self.host(host).keeper_pid, argv)

    def host_environment(self, host: VirtualHost | str, base: Mapping[str, str] | None = None) -> dict[str, str]:
        """The environment for a ROS 2 process on `host`: `base` (default: this process's) with
        multicast discovery on the subnet and UDP as the only transport (see the module docstring).
        ROS_DOMAIN_ID is left as `base` has it."""
        self.host(host)
        environment = dict(os.environ if base is None else base)
        for name in ROS_VARIABLES_REMOVED:
            environment.pop(name, None)
        environment.update(ROS_HOST_VARIABLES)
        return environment

    def enter(self, host: VirtualHost | str) -> None:
        """Move the calling thread into `host`'s network namespace, for good.

        For a process that must itself be on the network (an in-process ROS observer): call it from
        the main thread before `rclpy.init()` and before starting threads (threads keep the
        namespace they were started in; sockets keep the one they were opened in), and set
        `host_environment(host)` in `os.environ` too. Processes this thread starts later begin in
        that host unless told otherwise; `command()` does not depend on where they begin."""
        _setns(self.host(host).net_namespace)

    def on_host(self, host: VirtualHost | str, make: Callable[[], T]) -> T:
        """`make()` called on a short-lived thread inside `host`'s network namespace; what it opens
        there (a socket) stays there. For probes and tests; a program belongs in `command()`."""
        return _inside(self.host(host).net_namespace, make)

    def set_link(self, host: VirtualHost | str, up: bool) -> None:
        """Cut (`up=False`) or restore a host's link: while out, every frame to or from it is dropped."""
        host = self.host(host)
        if (host.port not in self._out) == up:
            return  # already as asked
        action = "delete" if up else "add"
        self._hub_run(["nft", action, "element", "bridge", BRIDGE, "out", f'{{ "{host.port}" }}'],
                      f"{'restore' if up else 'cut'} the link of {host.name}")  # fmt: skip
        if up:
            self._out.discard(host.port)
        else:
            self._out.add(host.port)

    def counters(self, host: VirtualHost | str) -> LinkCounters:
        """What crossed, and what was dropped on, `host`'s link so far."""
        host = self.host(host)
        named = self._nft_counters()
        port = self._port_statistics(host.port)
        queue_drops = self._tbf_drops(_in_namespace(self._hub, ["tc", "-s", "-j", "qdisc", "show", "dev", host.port]))
        queue_drops += self._tbf_drops(
            _in_namespace(host.keeper_pid, ["tc", "-s", "-j", "qdisc", "show", "dev", HOST_INTERFACE])
        )
        return LinkCounters(
            sent_packets=port["rx"]["packets"],  # what the hub's end receives, the host sent
            sent_bytes=port["rx"]["bytes"],
            received_packets=port["tx"]["packets"],
            received_bytes=port["tx"]["bytes"],
            lost_sent=named.get(f"{host.port}_lost_sent", 0),
            lost_received=named.get(f"{host.port}_lost_received", 0),
            outage_dropped=named.get(f"{host.port}_outage", 0),
            queue_dropped=queue_drops,
        )

    def _nft_counters(self) -> dict[str, int]:
        listing = self._hub_run(["nft", "-j", "list", "counters", "table", "bridge", BRIDGE], "read the counters")
        return {
            item["counter"]["name"]: item["counter"]["packets"]
            for item in json.loads(listing)["nftables"]
            if "counter" in item
        }

    def _port_statistics(self, port: str) -> dict[str, dict[str, int]]:
        listing = self._hub_run(["ip", "-s", "-j", "link", "show", "dev", port], "read the link statistics")
        return json.loads(listing)[0]["stats64"]

    @staticmethod
    def _tbf_drops(argv: list[str]) -> int:
        listing = json.loads(_run(argv, "read the rate limiter's statistics") or "[]")
        return sum(qdisc.get("drops", 0) for qdisc in listing if qdisc.get("kind") == "tbf")

    # --- removing -------------------------------------------------------------------------------

    def close(self) -> None:
        """Remove every host, link, rule and the bridge (idempotent).

        The keepers exit, and the kernel frees each namespace with all it holds. A host in which a
        process still runs lives on, cut off (loopback only), until that process exits: stop the
        processes first."""
        relays, self._relays = self._relays, []
        keepers, self._keepers = self._keepers, []
        for process in [*relays, *reversed(keepers)]:  # delay lines, hosts, then the hub
            _stop_keeper(process)
        self.hosts.clear()

    def __enter__(self) -> VirtualHosts:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __del__(self) -> None:
        if getattr(self, "_keepers", None) or getattr(self, "_relays", None):
            try:
                self.close()
            except Exception:
                pass  # at interpreter exit; the keepers see end-of-file anyway


def keeper_processes(run_id: str | None = None) -> list[int]:
    """Pids of the keepers and delay lines on this machine (of one run, or of all): none once a run is over."""
    label = "tiling-virtual-hosts:" + (f"{run_id}:" if run_id is not None else "")
    found = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/cmdline", "rb") as handle:
                arguments = handle.read().split(b"\0")
        except OSError:
            continue
        if any(argument.decode(errors="replace").startswith(label) for argument in arguments):
            found.append(int(entry))
    return found


if __name__ == "__main__" and sys.argv[1:2] == ["delay-line"]:
    # python virtual_hosts.py delay-line DELAY_MS HOST_TAP_FD PORT_TAP_FD LABEL (see _start_delay_line)
    _delay_line(float(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4]))
