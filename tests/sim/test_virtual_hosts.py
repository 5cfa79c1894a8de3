"""Virtual hosts: connectivity, multicast, loss, rate, outages, ROS 2 across hosts over the link (not
shared memory), and nothing left behind after close() or after the owner is killed."""

from __future__ import annotations

import json
import os
import signal
import socket
import struct
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from tiling_sim.virtual_hosts import (
    LinkCounters,
    LinkShape,
    VirtualHosts,
    VirtualHostsUnavailableError,
    check_available,
    keeper_processes,
)

HERE = Path(__file__).resolve().parent
PORT = 47000
SO_RCVBUFFORCE, SO_TIMESTAMPNS = 33, 35  # Linux socket options Python's socket module does not name


def _unavailable() -> str:
    try:
        check_available()
    except VirtualHostsUnavailableError as error:
        return f"virtual hosts unavailable here: {error}"
    return ""


needs_virtual_hosts = pytest.mark.skipif(bool(_unavailable()), reason=_unavailable() or "available")


@pytest.fixture(scope="module")
def hosts() -> Iterator[VirtualHosts]:
    with VirtualHosts(f"test{os.getpid()}") as made:
        made.add_host("robot")
        made.add_host("base")
        made.add_host("lossy5", LinkShape(loss_percent=5.0))
        made.add_host("lossy15", LinkShape(loss_percent=15.0))
        made.add_host("slow", LinkShape(rate_mbit=5.0))
        made.add_host("far", LinkShape(delay_ms=30.0))
        yield made


# --- sockets on a host ----------------------------------------------------------------------


def udp_socket(hosts: VirtualHosts, host: str, port: int = 0, group: str | None = None) -> socket.socket:
    def make() -> socket.socket:
        udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        udp.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        udp.setsockopt(socket.SOL_SOCKET, SO_RCVBUFFORCE, 16 << 20)  # no drops here, only on the link
        udp.setsockopt(socket.SOL_SOCKET, SO_TIMESTAMPNS, 1)  # arrival times from the kernel
        udp.bind(("", port))
        if group:
            membership = socket.inet_aton(group) + socket.inet_aton(hosts.host(host).address)
            udp.setsockopt(socket.IPPROTO_IP, socket.IP_ADD_MEMBERSHIP, membership)
        return udp

    return hosts.on_host(host, make)


def send(sender: socket.socket, address: str, count: int, size: int = 200, port: int = PORT) -> None:
    """`count` datagrams, paced a little so that no socket buffer on the way overflows."""
    payload = b"x" * size
    for k in range(count):
        sender.sendto(payload, (address, port))
        if k % 100 == 99:
            time.sleep(0.001)


def receive(receiver: socket.socket, quiet: float = 0.5) -> list[tuple[float, int]]:
    """(arrival time, size) of every datagram until none came for `quiet` seconds."""
    receiver.settimeout(quiet)
    arrivals = []
    while True:
        try:
            data, ancillary, _, _ = receiver.recvmsg(65536, 256)
        except TimeoutError:
            return arrivals
        stamp = next((struct.unpack("qq", d[:16]) for level, kind, d in ancillary
                      if level == socket.SOL_SOCKET and kind == SO_TIMESTAMPNS), (0, 0))  # fmt: skip
        arrivals.append((stamp[0] + stamp[1] * 1e-9, len(data)))


def burst(hosts: VirtualHosts, source: str, target: str, count: int, quiet: float = 0.5,
          counted: Callable[[], object] | None = None, link_up: bool = True) -> int:  # fmt: skip
    """How many of `count` datagrams from `source` reach `target`. `counted()` is called when the
    path is ready, just before the burst (to read counters)."""
    receiver = udp_socket(hosts, target, PORT)
    sender = udp_socket(hosts, source)
    with receiver, sender:
        if link_up:
            resolve_neighbour(sender, receiver, hosts.host(target).address)
        if counted is not None:
            counted()
        send(sender, hosts.host(target).address, count)
        return len(receive(receiver, quiet))


def resolve_neighbour(sender: socket.socket, receiver: socket.socket, address: str) -> None:
    """Send until one datagram arrives: the sender has the target's MAC address (ARP over a lossy
    link may take a retry, a second, during which the kernel queues only a few datagrams)."""
    receiver.settimeout(0.2)
    for _ in range(50):
        sender.sendto(b"?", (address, PORT))
        try:
            receiver.recv(16)
            break
        except TimeoutError:
            continue
    receiver.settimeout(0.05)
    try:
        while True:
            receiver.recv(16)  # late copies of the probe
    except TimeoutError:
        pass


# --- the network ------------------------------------------------------------------------------


@needs_virtual_hosts
def test_every_host_reaches_every_other_and_has_its_own_name(hosts: VirtualHosts) -> None:
    names = ["robot", "base", "slow", "far"]
    for source in names:
        for target in names:
            if source != target:
                assert burst(hosts, source, target, 3, quiet=0.1) == 3, f"{source} -> {target}"
    hostname = subprocess.run(hosts.command("robot", ["cat", "/proc/sys/kernel/hostname"]),
                              capture_output=True, text=True, check=True)  # fmt: skip
    assert hostname.stdout.strip() == "robot"
    assert {host.address for host in hosts.hosts.values()} == {f"10.213.0.{k}" for k in range(1, 7)}


@needs_virtual_hosts
def test_multicast_reaches_every_other_host(hosts: VirtualHosts) -> None:
    group = "239.255.0.1"  # the one DDS discovery uses
    receivers = {name: udp_socket(hosts, name, PORT + 1, group) for name in ("base", "slow", "lossy5")}
    sender = udp_socket(hosts, "robot")
    sender.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, 1)
    send(sender, group, 5, port=PORT + 1)
    counts = {name: len(receive(udp, quiet=0.3)) for name, udp in receivers.items()}
    for udp in (*receivers.values(), sender):
        udp.close()
    # lossy5 may lose one of five (5 % each); the others lose none
    assert counts["base"] == 5 and counts["slow"] == 5 and counts["lossy5"] >= 3, counts


@pytest.mark.parametrize(
    "source, target, expected_loss",
    [
        ("lossy5", "base", 0.05),  # the lossy host's uplink
        ("base", "lossy15", 0.15),  # the lossy host's downlink
        ("lossy5", "lossy15", 1 - 0.95 * 0.85),  # two lossy links, as station -> access point -> station
    ],
)
@needs_virtual_hosts
def test_random_loss_drops_about_the_share_asked_and_counts_it(
    hosts: VirtualHosts, source: str, target: str, expected_loss: float
) -> None:
    count = 3000
    before: dict[str, LinkCounters] = {}

    def read_counters() -> None:
        before.update({name: hosts.counters(name) for name in (source, target)})

    received = burst(hosts, source, target, count, counted=read_counters)
    after = {name: hosts.counters(name) for name in (source, target)}
    loss = 1 - received / count
    print(f"{source} -> {target}: {count - received} of {count} lost ({loss:.1%}, expected {expected_loss:.1%})")
    spread = 4.5 * (expected_loss * (1 - expected_loss) / count) ** 0.5  # kernel randomness: no seed
    assert abs(loss - expected_loss) < spread, f"{source} -> {target}: lost {loss:.3f}, expected {expected_loss}"
    dropped = (after[source].lost_sent - before[source].lost_sent) + (
        after[target].lost_received - before[target].lost_received
    )
    assert abs(dropped - (count - received)) <= 3, "every lost datagram is counted (give or take an ARP frame)"


def flood(hosts: VirtualHosts, source: str, target: str, seconds: float) -> list[tuple[float, int]]:
    """(arrival time, size) of the datagrams that reach `target` while `source` sends as fast as it can."""
    receiver = udp_socket(hosts, target, PORT + 2)
    sender = udp_socket(hosts, source)
    payload = b"y" * 1400
    with receiver, sender:
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            for _ in range(20):
                sender.sendto(payload, (hosts.host(target).address, PORT + 2))
        arrivals = receive(receiver)
    assert len(arrivals) > 10
    return arrivals


def throughput_mbit(arrivals: list[tuple[float, int]]) -> float:
    """Payload rate between the first and the last arrival."""
    elapsed = arrivals[-1][0] - arrivals[0][0]
    return sum(size for _, size in arrivals[1:]) * 8 / elapsed / 1e6


@needs_virtual_hosts
def test_rate_limit_holds_both_directions_near_5_mbit(hosts: VirtualHosts) -> None:
    unshaped_mbit = sum(size for _, size in flood(hosts, "robot", "base", 0.5)) * 8 / 0.5 / 1e6
    sending = throughput_mbit(flood(hosts, "slow", "base", 1.5))
    receiving = throughput_mbit(flood(hosts, "base", "slow", 1.5))
    print(f"throughput: 5 Mbit host sending {sending:.2f}, receiving {receiving:.2f} Mbit/s; unshaped at least "
          f"{unshaped_mbit:.0f} Mbit/s")  # fmt: skip
    # 1400 bytes of payload travel in 1442-byte frames: 4.85 Mbit/s of payload at 5 Mbit/s
    assert 4.2 < sending < 5.2, f"slow host sending: {sending:.2f} Mbit/s"
    assert 4.2 < receiving < 5.2, f"slow host receiving: {receiving:.2f} Mbit/s"
    # (a lower bound: the receiver's buffer fills within the half second)
    assert unshaped_mbit > 3 * 5, f"an unshaped link carries {unshaped_mbit:.1f} Mbit/s: the limit is the shaping"


@needs_virtual_hosts
def test_delay_line_delays_every_packet(hosts: VirtualHosts) -> None:
    """30 ms each way on "far"'s link: a round trip robot -> far -> robot takes 60 ms and a little."""
    pinger = udp_socket(hosts, "robot")
    echo = udp_socket(hosts, "far", PORT + 3)
    pinger.settimeout(2.0)
    echo.settimeout(0.1)
    done = threading.Event()

    def answer() -> None:
        while not done.is_set():
            try:
                data, sender = echo.recvfrom(64)
            except TimeoutError:
                continue
            echo.sendto(data, sender)

    answering = threading.Thread(target=answer)
    answering.start()
    round_trips = []
    with pinger, echo:
        for _ in range(40):
            started = time.monotonic()
            pinger.sendto(b"ping", (hosts.host("far").address, PORT + 3))
            pinger.recvfrom(64)
            round_trips.append((time.monotonic() - started) * 1000)
            time.sleep(0.01)
        done.set()
        answering.join()
    round_trips.sort()
    median = round_trips[len(round_trips) // 2]
    print(f"round trip through a 30 ms delay line: min {round_trips[0]:.1f}, median {median:.1f}, "
          f"max {round_trips[-1]:.1f} ms")  # fmt: skip
    assert round_trips[0] >= 60.0, "never faster than the delay"
    assert median < 70.0, "the delay line adds little of its own"


@needs_virtual_hosts
def test_outage_stops_both_directions_and_restores(hosts: VirtualHosts) -> None:
    before = hosts.counters("robot")
    hosts.set_link("robot", False)
    hosts.set_link("robot", False)  # idempotent
    try:
        assert burst(hosts, "robot", "base", 200, link_up=False) == 0
        assert burst(hosts, "base", "robot", 200, link_up=False) == 0
        during = hosts.counters("robot")
    finally:
        hosts.set_link("robot", True)
    hosts.set_link("robot", True)
    assert during.outage_dropped - before.outage_dropped >= 400
    assert burst(hosts, "robot", "base", 200) == 200
    assert burst(hosts, "base", "robot", 200) == 200


# --- ROS 2 across two hosts -------------------------------------------------------------------


class Listener:
    """The listener process's lines "TOPIC N TIME", collected by a thread."""

    def __init__(self, process: subprocess.Popen[str]) -> None:
        self.process = process
        self.messages: list[tuple[str, int, float]] = []
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        assert self.process.stdout is not None
        for line in self.process.stdout:
            parts = line.split()
            if len(parts) == 3 and parts[0] in ("chatter", "plain"):
                self.messages.append((parts[0], int(parts[1]), float(parts[2])))

    def count(self, topic: str, after: float = 0.0) -> int:
        return sum(1 for t, _, at in list(self.messages) if t == topic and at > after)

    def wait_for(self, topic: str, count: int, after: float = 0.0, timeout: float = 30.0) -> float:
        deadline = time.monotonic() + timeout
        while self.count(topic, after) < count:
            assert time.monotonic() < deadline, f"only {self.count(topic, after)} {topic} messages in {timeout} s"
            assert self.process.poll() is None, "the listener exited"
            time.sleep(0.05)
        return time.monotonic()


def shared_memory_files(pid: int) -> set[str]:
    """The Fast DDS shared-memory files a process has mapped (segments and port files)."""
    with open(f"/proc/{pid}/maps") as maps:
        return {line.split()[-1] for line in maps if "/dev/shm/fastrtps" in line}


@needs_virtual_hosts
@pytest.mark.ros
def test_ros_messages_cross_the_link_not_shared_memory(hosts: VirtualHosts) -> None:
    peer = [sys.executable, str(HERE / "virtual_hosts_peer.py")]
    listener_process = subprocess.Popen(hosts.command("base", [*peer, "listen"]), env=hosts.host_environment("base"),
                                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)  # fmt: skip
    talker = subprocess.Popen(hosts.command("robot", [*peer, "talk", "0.05"]), env=hosts.host_environment("robot"),
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)  # fmt: skip
    listener = Listener(listener_process)
    try:
        listener.wait_for("chatter", 1)
        sent_before = hosts.counters("robot").sent_packets
        start = time.monotonic()
        listener.wait_for("chatter", 20, after=start)
        listener.wait_for("plain", 20, after=start)
        crossed = hosts.counters("robot").sent_packets - sent_before
        assert crossed >= 40, f"{crossed} frames crossed the link for >= 40 messages"
        assert shared_memory_files(talker.pid) == set() and shared_memory_files(listener_process.pid) == set()

        hosts.set_link("robot", False)
        cut = time.monotonic() + 0.2  # a message already on its way may still arrive
        time.sleep(2.5)
        assert listener.count("chatter", cut) == 0 and listener.count("plain", cut) == 0, "data without a link"
        hosts.set_link("robot", True)
        restored = time.monotonic()
        resumed = listener.wait_for("chatter", 5, after=restored, timeout=15)
        print(f"messages resumed {resumed - restored:.2f} s after a 2.5 s outage")
    finally:
        hosts.set_link("robot", True)
        for process in (talker, listener_process):
            process.send_signal(signal.SIGINT)
        codes = [process.wait(timeout=15) for process in (talker, listener_process)]
    assert codes == [0, 0]


# --- nothing left behind ----------------------------------------------------------------------


def namespaces_in_use() -> set[int]:
    """Inodes of every network namespace a process or thread is in, or holds open, on this machine."""
    inodes: set[int] = set()
    for pid in filter(str.isdigit, os.listdir("/proc")):
        for path in (f"/proc/{pid}/ns/net", *(f"/proc/{pid}/fd/{fd}" for fd in _fds(pid))):
            try:
                target = os.readlink(path)
            except OSError:
                continue
            if target.startswith("net:["):
                inodes.add(int(target[5:-1]))
    return inodes


def _fds(pid: str) -> list[str]:
    try:
        return os.listdir(f"/proc/{pid}/fd")
    except OSError:
        return []


def root_namespace_mentions(run_id: str) -> list[str]:
    """Anything of a run visible in the root namespace: named namespaces, links, nftables tables."""
    listings = [
        subprocess.run(argv, capture_output=True, text=True).stdout
        for argv in (["ip", "netns", "list"], ["ip", "-o", "link", "show"], ["nft", "list", "tables"])
    ]
    words = " ".join(listings).split()
    return [w for w in words if run_id in w or w.rstrip(":") == "air"]


def running(pid: int) -> bool:
    """Whether `pid` still runs (a zombie waiting for init to reap it does not, and holds nothing)."""
    try:
        with open(f"/proc/{pid}/stat") as stat:
            return stat.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def wait_until_gone(keepers: list[int], namespaces: list[int], timeout: float = 10.0) -> None:
    deadline = time.monotonic() + timeout
    while True:
        alive = [pid for pid in keepers if running(pid)]
        held = set(namespaces) & namespaces_in_use()
        if not alive and not held:
            return
        assert time.monotonic() < deadline, f"still there: keepers {alive}, namespaces {held}"
        time.sleep(0.1)


@needs_virtual_hosts
def test_close_removes_everything_and_can_be_repeated() -> None:
    run_id = f"close{os.getpid()}"
    hosts = VirtualHosts(run_id)
    hosts.add_host("a", LinkShape(loss_percent=5.0, rate_mbit=5.0))
    hosts.add_host("b")
    keepers = hosts.keeper_pids
    namespaces = [os.stat(f"/proc/{pid}/ns/net").st_ino for pid in keepers]
    assert set(namespaces) <= namespaces_in_use() and len(set(namespaces)) == 3
    assert sorted(keeper_processes(run_id)) == sorted(keepers)
    hosts.close()
    hosts.close()
    wait_until_gone(keepers, namespaces)
    assert keeper_processes(run_id) == []
    assert root_namespace_mentions(run_id) == []


@needs_virtual_hosts
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM, signal.SIGKILL], ids=["SIGINT", "SIGTERM", "SIGKILL"])
def test_nothing_outlives_an_owner_that_is_signalled(sig: signal.Signals) -> None:
    run_id = f"owner{os.getpid()}{sig.name}"
    owner = subprocess.Popen([sys.executable, str(HERE / "virtual_hosts_owner.py"), run_id],
                             stdout=subprocess.PIPE, text=True)  # fmt: skip
    assert owner.stdout is not None
    made = json.loads(owner.stdout.readline())
    assert set(made["namespaces"]) <= namespaces_in_use()
    owner.send_signal(sig)
    owner.wait(timeout=15)
    wait_until_gone(made["keepers"] + made["processes"], made["namespaces"])
    assert keeper_processes(run_id) == []
    assert root_namespace_mentions(run_id) == []


def test_without_root_one_clear_line(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(os, "geteuid", lambda: 1000)
    with pytest.raises(VirtualHostsUnavailableError) as raised:
        VirtualHosts()
    assert str(raised.value) == "virtual hosts need root (network namespaces, bridges, nftables): run as root"
    monkeypatch.setattr(os, "geteuid", lambda: 0)
    monkeypatch.setenv("PATH", "/nonexistent")
    with pytest.raises(VirtualHostsUnavailableError, match=r"^virtual hosts need the 'ip' command: .*iproute2"):
        VirtualHosts()
