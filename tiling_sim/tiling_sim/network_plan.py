"""Where each process of an experiment runs, and how the robots' links behave (`--hosts netns`).

With `--hosts netns` every computer of the team is a host of its own (`virtual_hosts`): the base
station (planner, auction node), each assembly robot (its assembly_node and the body that serves its
place_tile action), each scanning robot (vi_node, vi_explorer and its body with the Kinect), and the
simulated world. The robots' links are shaped like a busy WiFi (loss, rate, outages); the base
station and the world are wired: the paper's robots talked over 802.11b, the world is no computer
at all, and the runner's observer watches from a wired host too.

Simulated time crosses the links as `/clock` like everything else, so a link's wall-clock delays
(a lost sample repaired, a bid waiting behind a queue) cost `real_time_factor` times as much
simulated time. `DEFAULT_NETNS_TIME_FACTOR` keeps a quarter-second delay near one simulated second,
small beside the 10 s a placement takes; a user may choose another with `--real-time-factor`.
Outages are given in simulated time, as everything else in a trial.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

from tiling_sim.sim_settings import VI_ROBOT

DEFAULT_NETNS_TIME_FACTOR = 5.0
WIRED_HOSTS = ("base", "world", "observer")


class NetworkPlanError(ValueError):
    """A network option that cannot be used; the message is one line."""


@dataclass(frozen=True)
class Outage:
    host: str  # a robot: robot1, ..., vi
    at: float  # s of simulated time from the start of the build
    duration: float  # s of simulated time

    @classmethod
    def parse(cls, text: str) -> Outage:
        """`ROBOT:AT:SECONDS`, e.g. robot2:120:40."""
        parts = text.split(":")
        try:
            host, at, duration = parts[0], float(parts[1]), float(parts[2])
        except (IndexError, ValueError):
            raise NetworkPlanError(f"--link-outage {text}: expected ROBOT:AT:SECONDS, e.g. robot2:120:40") from None
        if len(parts) != 3 or not host or at < 0 or duration <= 0:
            raise NetworkPlanError(f"--link-outage {text}: expected ROBOT:AT:SECONDS with AT >= 0 and SECONDS > 0")
        return cls(host, at, duration)

    def out_at(self, t: float) -> bool:
        return self.at <= t < self.at + self.duration


@dataclass(frozen=True)
class NetworkSettings:
    hosts: str = ""  # "": every process on this host; "netns": a host per computer
    loss_percent: float = 0.0  # per robot link, each direction
    rate_mbit: float | None = None  # per robot link, each direction
    delay_ms: float = 0.0
    outages: tuple[Outage, ...] = field(default_factory=tuple)

    @property
    def separate_hosts(self) -> bool:
        return self.hosts == "netns"

    def check(self, robots: list[str], vi_robots: Sequence[str] = (VI_ROBOT,)) -> None:
        """One line about the first option that does not fit the team."""
        shaped = self.loss_percent or self.rate_mbit is not None or self.delay_ms or self.outages
        if shaped and not self.separate_hosts:
            raise NetworkPlanError("--link-loss, --link-rate, --link-delay and --link-outage need --hosts netns")
        known = [*robots, *vi_robots]
        for outage in self.outages:
            if outage.host not in known:
                raise NetworkPlanError(f"--link-outage {outage.host}: no such robot (robots: {', '.join(known)})")

    def as_dict(self) -> dict[str, object]:
        return {
            "hosts": self.hosts or "one", "link_loss_percent": self.loss_percent, "link_rate_mbit": self.rate_mbit,
            "link_delay_ms": self.delay_ms,
            "link_outages": [{"robot": o.host, "at": o.at, "seconds": o.duration} for o in self.outages],
        }


def host_of(process: str, robots: list[str], vi_robots: Sequence[str] = (VI_ROBOT,)) -> str:
    """The host a process of the experiment runs on (its name as the runner starts it: vi_node,
    vi_explorer, sim_vi for the one VI robot; viK_vi_node, viK_vi_explorer, viK_body for several)."""
    if process in ("planner_node", "auction_node"):
        return "base"
    if process == "sim_world":
        return "world"
    if process in ("vi_node", "vi_explorer", "sim_vi"):
        return VI_ROBOT
    vi = next((name for name in vi_robots if process.startswith(f"{name}_")), None)
    if vi is not None:
        return vi
    robot = process.removesuffix("_body")
    if robot in robots:
        return robot
    raise ValueError(f"no host for process {process}")


def links_out(outages: tuple[Outage, ...], t: float) -> set[str]:
    """The hosts whose link is out at simulated time `t`."""
    return {o.host for o in outages if o.out_at(t)}
