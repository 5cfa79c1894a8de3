"""Which host each process of an experiment runs on, and the link options (ROS-free)."""

from __future__ import annotations

import pytest

from tiling_sim.network_plan import NetworkPlanError, NetworkSettings, Outage, host_of, links_out

ROBOTS = ["robot1", "robot2"]


def test_every_process_runs_on_its_computer() -> None:
    hosts = {p: host_of(p, ROBOTS) for p in ("planner_node", "auction_node", "sim_world", "robot1", "robot1_body",
                                             "robot2", "robot2_body", "vi_node", "vi_explorer", "sim_vi")}
    assert hosts == {"planner_node": "base", "auction_node": "base", "sim_world": "world", "robot1": "robot1",
                     "robot1_body": "robot1", "robot2": "robot2", "robot2_body": "robot2", "vi_node": "vi",
                     "vi_explorer": "vi", "sim_vi": "vi"}
    with pytest.raises(ValueError, match="no host for process robot3"):
        host_of("robot3", ROBOTS)


def test_an_outage_reads_robot_at_seconds_in_simulated_time() -> None:
    outage = Outage.parse("robot2:120:40")
    assert outage == Outage("robot2", 120.0, 40.0)
    assert links_out((outage,), 119.9) == set() and links_out((outage,), 120.0) == {"robot2"}
    assert links_out((outage,), 159.9) == {"robot2"} and links_out((outage,), 160.0) == set()


@pytest.mark.parametrize("text", ["robot2", "robot2:120", "robot2:x:40", ":1:2", "robot2:1:0", "robot2:1:2:3"])
def test_a_malformed_outage_gets_one_line(text: str) -> None:
    with pytest.raises(NetworkPlanError, match="ROBOT:AT:SECONDS"):
        Outage.parse(text)


def test_link_options_need_separate_hosts_and_known_robots() -> None:
    with pytest.raises(NetworkPlanError, match="need --hosts netns"):
        NetworkSettings(loss_percent=5.0).check(ROBOTS)
    with pytest.raises(NetworkPlanError, match="no such robot"):
        NetworkSettings(hosts="netns", outages=(Outage("robot7", 1.0, 2.0),)).check(ROBOTS)
    NetworkSettings(hosts="netns", loss_percent=5.0, rate_mbit=5.0, outages=(Outage("vi", 1.0, 2.0),)).check(ROBOTS)
    assert NetworkSettings().as_dict()["hosts"] == "one"
