"""The network an experiment's processes talk over: this host, or a virtual host per computer.

`TeamNetwork` is what the runner asks where to start a process and how its links behave now; with
`--hosts netns` it builds the hosts of `network_plan` with `virtual_hosts` (robots shaped, the
base station, the world and the runner's observer wired) and cuts and restores the robots' links
as the outages say. On one host it changes nothing.

Over the shaped links every ROS process loads config/fastdds_wifi.xml: reliable topics repaired
every 100 ms instead of every 3 s (the measurement is in that file).
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field

from tiling_sim.network_plan import WIRED_HOSTS, NetworkSettings, host_of, links_out
from tiling_sim.sim_settings import VI_ROBOT
from tiling_sim.virtual_hosts import LinkShape, VirtualHosts


@dataclass(frozen=True)
class LinkChange:
    t: float  # s of simulated time
    host: str
    up: bool


@dataclass
class TeamNetwork:
    settings: NetworkSettings
    robots: list[str]
    vi_robots: Sequence[str] = (VI_ROBOT,)
    hosts: VirtualHosts | None = None
    dds_profile: str = ""  # Fast DDS XML profile every process on a host loads
    out: set[str] = field(default_factory=set)

    @classmethod
    def build(cls, settings: NetworkSettings, robots: list[str], run_id: str, dds_profile: str = "",
              vi_robots: Sequence[str] = (VI_ROBOT,)) -> TeamNetwork:
        """The network; with separate hosts, the runner's own thread moves onto the observer host
        (call before rclpy.init and before starting threads). Raises VirtualHostsError (one line)."""
        network = cls(settings, robots, tuple(vi_robots), dds_profile=dds_profile)
        if not settings.separate_hosts:
            return network
        network.hosts = VirtualHosts(run_id)
        shaped = cls.link_shape(settings)
        for name in WIRED_HOSTS:
            network.hosts.add_host(name)
        for name in [*robots, *vi_robots]:
            network.hosts.add_host(name, shaped)
        network.hosts.enter("observer")
        os.environ.update(network.environment("observer", os.environ))
        return network

    @staticmethod
    def link_shape(settings: NetworkSettings) -> LinkShape:
        """Every robot's link (ValueError, one line, for impossible numbers)."""
        return LinkShape(settings.loss_percent, settings.rate_mbit, settings.delay_ms)

    def describe(self) -> str:
        if self.hosts is None:
            return "Hosts: one (every process on this machine)"
        return (f"Hosts: base, world, {', '.join([*self.robots, *self.vi_robots])} (network namespaces on one bridge); "
                f"robots' links: {self.link_shape(self.settings)}")

    def command(self, process: str, argv: Sequence[str]) -> list[str]:
        if self.hosts is None:
            return list(argv)
        return self.hosts.command(host_of(process, self.robots, self.vi_robots), argv)

    def environment(self, process: str, base: Mapping[str, str]) -> dict[str, str]:
        if self.hosts is None:
            return dict(base)
        host = process if process in WIRED_HOSTS else host_of(process, self.robots, self.vi_robots)
        environment = self.hosts.host_environment(host, base)
        if self.dds_profile:
            environment["FASTRTPS_DEFAULT_PROFILES_FILE"] = self.dds_profile
        return environment

    def follow_outages(self, t: float) -> list[LinkChange]:
        """Cut or restore links for simulated time `t`; the changes made."""
        if self.hosts is None:
            return []
        due = links_out(self.settings.outages, t)
        changes = [LinkChange(t, h, False) for h in sorted(due - self.out)]
        changes += [LinkChange(t, h, True) for h in sorted(self.out - due)]
        for change in changes:
            self.hosts.set_link(change.host, change.up)
        self.out = due
        return changes

    def restore_links(self) -> None:
        """Every link up (between trials)."""
        if self.hosts is not None:
            for host in sorted(self.out):
                self.hosts.set_link(host, True)
        self.out = set()

    def counters(self) -> dict[str, dict[str, int]]:
        """What went over each robot's link so far (frames and bytes, dropped by loss or outage)."""
        if self.hosts is None:
            return {}
        return {name: asdict(self.hosts.counters(name)) for name in [*self.robots, *self.vi_robots]}

    def close(self) -> None:
        if self.hosts is not None:
            self.hosts.close()
