"""End to end over real ROS processes: build, inspect, correct (paper sections 2.3 and 3).

Each test runs the experiment command, which starts the simulated world, the planner, the auction
node, one assembly node per robot and the VI robot's inspection and exploration nodes as separate
OS processes on a private ROS domain, and checks what happened from the run's results.
"""

from __future__ import annotations

import json
import shutil
import signal
import subprocess
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import yaml
from conftest import REPO, STRUCTURES

from tiling_sim.virtual_hosts import VirtualHostsUnavailableError, check_available, keeper_processes


def virtual_hosts_unavailable_reason() -> str:
    try:
        check_available()
    except VirtualHostsUnavailableError as error:
        return str(error)
    return ""


def virtual_hosts_available() -> bool:
    return not virtual_hosts_unavailable_reason()


def run_experiment(
    report: Path, *args: str, timeout: float = 240.0, real_time_factor: float = 30.0
) -> tuple[subprocess.CompletedProcess[str], dict[str, Any]]:
    command = [
        str(REPO / "install/tiling_sim/lib/tiling_sim/experiment"),
        "--structure", str(STRUCTURES / "paper_14.yaml"), "--report", str(report), "--quiet",
        "--real-time-factor", str(real_time_factor), "--no-baseline", *args,
    ]
    result = subprocess.run(command, cwd=REPO, capture_output=True, text=True, timeout=timeout)
    results_file = report / "results.json"
    data = json.loads(results_file.read_text()) if results_file.exists() else {}
    data["log_tails"] = _log_tails_of_unclean_exits(report, data)
    return result, data


def _log_tails_of_unclean_exits(report: Path, data: dict[str, Any], lines: int = 60) -> str:
    """The end of each log of a node that did not stop cleanly (a crash's stacks, from the node's
    faulthandler), for the assertion: the report folder is gone once the test ends."""
    tails = []
    for trial in data.get("trials", []):
        for name in trial.get("unclean_exits", {}):
            log = report / "logs" / f"trial_{trial['trial']:02d}" / f"{name}.log"
            text = log.read_text(errors="replace").splitlines()[-lines:] if log.exists() else ["(no log)"]
            tails.append(f"--- {log.name}, trial {trial['trial']}:\n" + "\n".join(text))
    return "\n".join(tails)


@pytest.fixture
def experiment(tmp_path: Path):  # type: ignore[no-untyped-def]
    return lambda *args, **kw: run_experiment(tmp_path / "report", *args, **kw)


pytestmark = [pytest.mark.ros, pytest.mark.slow]


def config_with(folder: Path, package: str, **parameters: object) -> Path:
    """A copy of the product's parameter files (made unless `folder` exists) with some of one node's
    parameters changed."""
    if not folder.exists():
        shutil.copytree(REPO / "config", folder)
    path = folder / f"{package}.yaml"
    document = yaml.safe_load(path.read_text())
    document["/**"]["ros__parameters"].update(parameters)
    path.write_text(yaml.safe_dump(document))
    return folder


def _only_trial(data: dict) -> dict:  # type: ignore[type-arg]
    (trial,) = data["trials"]
    assert trial["unclean_exits"] == {}, f"nodes that did not stop cleanly at Ctrl-C\n{data['log_tails']}"
    return trial


def test_removed_tile_is_detected_auctioned_and_replaced(experiment, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    # The robot that finds the tile's support gone waits for a scan far longer than inspection needs
    # (20-60 s here), so the auction is opened by a scan and never by the robot's report timing out.
    # The assembly robots are kept out of the Kinect's view: standing beside the structure, they hide
    # enough of it that in about half of these one-trial runs no scan aligns at all (a known weakness
    # of the alignment, measured in the issue-6 note); this test is about what follows a detection.
    config = config_with(tmp_path / "config", "auction_node", unconfirmed_report_timeout=600.0)
    config_with(config, "tiling_sim", robots_in_view=False)
    result, data = experiment("--trials", "1", "--removals", "1", "--seed", "3", "--inspection-only",
                              "--config", str(config), real_time_factor=20.0)
    assert result.returncode == 0, result.stdout[-2000:] + result.stderr[-2000:]
    trial = _only_trial(data)
    assert trial["complete"] and trial["removed"] == 1 and trial["detected"] == 1
    assert trial["found_by_robot"] == 0  # robots' reports of absent supports are ignored
    (removal,) = trial["removals"]
    replaced = [p for p in trial["placements"] if p["tile"] == removal["tile"] and p["t"] > removal["t"]]
    assert replaced, "the removed tile was never placed again"
    won = [d for d in trial["decisions"] if f"for tile {removal['tile']}:" in d and " wins with " in d]
    assert won and replaced[0]["robot"] in won[0]
    events = json.loads((tmp_path / "report" / "logs" / "trial_01" / "events.json").read_text())
    (gone,) = [e for e in events if e["kind"] == "removed"]
    assert gone["tile"] == removal["tile"] and abs(gone["t"] - removal["t"]) < 0.01
    assert sum(e["kind"] == "placed" for e in events) == len(trial["placements"])
    assert "Every trial finished the structure correctly: yes (1/1)" in result.stdout
    # the plan the trial started from, as the planner gave it (paper_14, 2 robots: 245 s, bound 244 s)
    assert data["lower_bound"] <= data["planned_makespan"] <= 1.05 * data["lower_bound"]
    assert f"Planned makespan {data['planned_makespan']:.0f} s (lower bound {data['lower_bound']:.0f} s)" \
        in result.stdout


@pytest.mark.timeout(340)  # under faulthandler_timeout (pyproject.toml)
def test_two_vi_robots_look_from_apart_and_their_scans_find_a_removed_tile(experiment, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    # gate_9: two VI robots judge every frame from the start (the clock waits for each verdict), which on
    # paper_14 took 500 s of wall time on a loaded host; the smaller one (190 s there) asks the same of them
    config = config_with(tmp_path / "config", "auction_node", unconfirmed_report_timeout=600.0)
    result, data = experiment("--trials", "1", "--removals", "1", "--seed", "3", "--inspection-only",
                              "--structure", str(STRUCTURES / "gate_9.yaml"),
                              "--vi-robots", "2", "--config", str(config), real_time_factor=20.0, timeout=320.0)
    assert result.returncode == 0, result.stdout[-2000:] + result.stderr[-2000:]
    assert data["vi_robots"] == ["vi1", "vi2"] and "+ 2 VI robots" in result.stdout
    trial = _only_trial(data)
    assert trial["complete"] and trial["removed"] == 1 and trial["detected"] == 1
    assert set(trial["scans_judged_by"]) == {"vi1", "vi2"} and min(trial["scans_judged_by"].values()) >= 5
    logs = tmp_path / "report" / "logs" / "trial_01"
    claimed = {}
    for robot in ("vi1", "vi2"):
        lines = (logs / f"{robot}_vi_explorer.log").read_text().splitlines()
        claimed[robot] = [line.split("next viewpoint ")[1].split(",")[:2] for line in lines if "next viewpoint" in line]
        assert claimed[robot], f"{robot} never chose a viewpoint"
    assert claimed["vi1"][0] != claimed["vi2"][0]  # they start apart and look from near where they stand


def test_a_robot_finding_a_support_absent_gets_it_replaced_without_inspection(experiment) -> None:  # type: ignore[no-untyped-def]
    result, data = experiment("--trials", "1", "--removals", "1", "--seed", "3", "--no-inspection")
    trial = _only_trial(data)
    assert trial["complete"], result.stdout[-2000:]
    assert (trial["detected"], trial["found_by_robot"]) == (0, 1)
    (removal,) = trial["removals"]
    assert any(f"tile {removal['tile']} was placed but" in d and "found it missing when placing tile" in d
               for d in trial["decisions"])
    assert any(p["tile"] == removal["tile"] and p["t"] > removal["found_by_robot_at"] for p in trial["placements"])
    assert not any("gave up" in d for d in trial["decisions"])  # the blocked tile waited, it was not given up


def test_killed_robot_has_its_tiles_finished_by_the_other(experiment) -> None:  # type: ignore[no-untyped-def]
    result, data = experiment("--trials", "1", "--removals", "0", "--kill-robot", "robot2")
    trial = _only_trial(data)
    assert trial["complete"], result.stdout[-2000:]
    assert any("robot2 lost" in d for d in trial["decisions"])
    assert any("replanned after losing robot2" in d for d in trial["decisions"])
    killed_at = max(p["t"] for p in trial["placements"] if p["robot"] == "robot2")
    after = {p["tile"] for p in trial["placements"] if p["t"] > killed_at}
    assert after and all(p["robot"] == "robot1" for p in trial["placements"] if p["t"] > killed_at)
    assert len({p["tile"] for p in trial["placements"]}) == 14


def test_a_shifted_tile_and_a_wrong_tile_under_another_are_found_and_repaired(experiment) -> None:  # type: ignore[no-untyped-def]
    # seed 13 (trial seed 14): square 10 lands shifted 3.3 cm, a long rectangle's place 11 gets an
    # octagon, and triangle 13 is put on it before inspection can tell: the repair takes 13 off first
    result, data = experiment("--trials", "1", "--removals", "0", "--misplacements", "1", "--wrong-tiles", "1",
                              "--seed", "13", timeout=420.0)
    trial = _only_trial(data)
    assert trial["complete"], result.stdout[-2000:] + result.stderr[-2000:]
    by_tile = {m["tile"]: m for m in trial["misplacements"]}
    assert {(tile, m["kind"]) for tile, m in by_tile.items()} == {(10, "shift"), (11, "wrong_type")}
    for m in by_tile.values():
        assert m["injected_at"] < m["detected_at"] < m["repaired_at"], m
    assert trial["false_repairs"] == 0, trial["decisions"]  # no tile in place was ever repaired
    repairs = [d for d in trial["decisions"] if "lying wrong: repair" in d]
    assert len(repairs) == 2 and all(" for tile 10 " in d or " for tile 11 " in d for d in repairs)
    placed_13 = [p["t"] for p in trial["placements"] if p["tile"] == 13]
    if any("13 rests on it and comes off first" in d for d in repairs):
        # put back after the right tile 11 went in: both end correct (the world says complete)
        assert len(placed_13) == 2 and placed_13[1] > by_tile[11]["repaired_at"]
    assert trial["duplicate_placements"] == [] and trial["lost_placements"] == [], trial["decisions"]
    assert "Placements that landed wrong, and their repair" in result.stdout


def test_robot_that_never_bids_does_not_block_an_auction(experiment) -> None:  # type: ignore[no-untyped-def]
    result, data = experiment("--trials", "1", "--removals", "1", "--seed", "3", "--silent-robot", "robot2")
    trial = _only_trial(data)
    assert trial["complete"], result.stdout[-2000:]
    awards = [d for d in trial["decisions"] if " wins with " in d]
    assert awards and all("robot1 wins" in d and "no answer from robot2" in d for d in awards)


def _processes_of_run() -> dict[str, list[int]]:
    """Live processes started by experiment runs, by their run marker."""
    runs: dict[str, list[int]] = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            environ = (entry / "environ").read_bytes().split(b"\0")
            state = (entry / "stat").read_text().rsplit(")", 1)[1].split()[0]
        except OSError:
            continue
        for item in environ:
            if item.startswith(b"TILING_EXPERIMENT_RUN=") and state != "Z":
                runs.setdefault(item.split(b"=", 1)[1].decode(), []).append(int(entry.name))
    return runs


def interrupt_a_run(tmp_path: Path, *options: str, nodes: int, running: float,
                    check_running: Callable[[], None] = lambda: None) -> tuple[set[str], str]:
    """Start an experiment, wait until `nodes` of its processes run (then `check_running()`), Ctrl-C it
    `running` s later.
    Returns the runs that existed before it, and its stderr; asserts it stopped as Ctrl-C asks."""
    before = set(_processes_of_run())
    command = [str(REPO / "install/tiling_sim/lib/tiling_sim/experiment"), "--structure",
               str(STRUCTURES / "paper_14.yaml"), "--report", str(tmp_path), "--trials", "1", "--quiet", *options]
    runner = subprocess.Popen(command, cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 60
        children: list[int] = []
        while time.monotonic() < deadline and len(children) < nodes:
            children = [p for run, pids in _processes_of_run().items() if run not in before for p in pids]
            time.sleep(0.2)
        assert len(children) >= nodes, "the run's nodes did not start"
        check_running()
        time.sleep(running)
        runner.send_signal(signal.SIGINT)
        _, stderr = runner.communicate(timeout=30)
    finally:
        if runner.poll() is None:
            runner.kill()
    assert runner.returncode == 130, stderr
    assert "interrupted: every node was stopped" in stderr and "Traceback" not in stderr
    time.sleep(0.5)
    assert [p for run, pids in _processes_of_run().items() if run not in before for p in pids] == []
    return before, stderr


def test_ctrl_c_stops_the_run_and_leaves_no_process(tmp_path: Path) -> None:
    interrupt_a_run(tmp_path, nodes=5, running=2.0)
    # what the world saw happen until then is kept
    assert isinstance(json.loads((tmp_path / "logs" / "trial_00" / "events.json").read_text()), list)


def test_ctrl_c_in_a_later_trial_keeps_the_report_of_the_trials_finished_before(tmp_path: Path) -> None:
    def baseline_finished() -> None:
        deadline = time.monotonic() + 400  # a busy host slows the baseline, it does not stop it
        while not (tmp_path / "logs" / "trial_01").exists() and time.monotonic() < deadline:
            time.sleep(0.2)
        assert (tmp_path / "logs" / "trial_01").exists(), "trial 1 did not start"

    _, stderr = interrupt_a_run(tmp_path, "--real-time-factor", "30", nodes=5, running=3.0,
                                check_running=baseline_finished)
    assert stderr.count("interrupted:") == 1 and "the 1 trial(s) finished before are in" in stderr
    data = json.loads((tmp_path / "results.json").read_text())
    assert data["interrupted"] is True
    (baseline,) = data["trials"]
    assert baseline["trial"] == 0 and baseline["complete"]
    assert "Interrupted: only the 1 trial(s) finished before are reported" in (tmp_path / "report.md").read_text()


def test_runner_failure_leaves_no_process(experiment) -> None:  # type: ignore[no-untyped-def]
    before = set(_processes_of_run())
    floating = REPO / "tests/data/structures/invalid/floating_tile.yaml"
    result, _ = experiment("--trials", "1", "--structure", str(floating))
    assert result.returncode == 2
    assert result.stderr.startswith("error: ") and "floating" in result.stderr and "Traceback" not in result.stderr
    assert [p for run, pids in _processes_of_run().items() if run not in before for p in pids] == []


def test_bad_command_lines_get_one_clear_error_and_start_nothing(tmp_path: Path) -> None:
    broken = tmp_path / "broken.yaml"
    broken.write_text("tiles: [ {id: 1, type: square")
    experiment = str(REPO / "install/tiling_sim/lib/tiling_sim/experiment")
    for args, says in (
        (["--config", str(tmp_path / "absent")], "no such folder of parameter files"),
        (["--structure", str(broken)], str(broken)),
        (["--robots", "0"], "--robots must be >= 1"),
        (["--link-loss", "5"], "need --hosts netns"),
        (["--hosts", "netns", "--link-outage", "robot9:10:5"], "no such robot"),
        (["--hosts", "netns", "--link-outage", "robot2:ten:5"], "ROBOT:AT:SECONDS"),
        (["--hosts", "netns", "--link-loss", "120"], "link loss must be"),
    ):
        result = subprocess.run([experiment, *args, "--report", str(tmp_path / "report")], cwd=REPO,
                                capture_output=True, text=True, timeout=60)
        assert result.returncode == 2 and says in result.stderr, result.stderr
        assert "Traceback" not in result.stderr and not (tmp_path / "report").exists()


@pytest.mark.skipif(not virtual_hosts_available(), reason=virtual_hosts_unavailable_reason())
@pytest.mark.skipif(shutil.which("capsh") is None, reason="capsh (Debian libcap2-bin) is not installed")
def test_hosts_without_network_capabilities_get_one_line_and_leave_nothing(tmp_path: Path) -> None:
    """Root in a container without CAP_NET_ADMIN and CAP_SYS_ADMIN: the kernel refuses the first
    namespace; one line, exit 2, no report, no namespace keeper or node left."""
    before = _processes_of_run()
    experiment = REPO / "install/tiling_sim/lib/tiling_sim/experiment"
    result = subprocess.run(
        ["capsh", "--drop=cap_net_admin,cap_sys_admin", "--", "-c",
         f"exec {experiment} --hosts netns --trials 1 --report {tmp_path / 'report'}"],
        cwd=REPO, capture_output=True, text=True, timeout=60)  # fmt: skip
    assert result.returncode == 2, result.stderr
    assert result.stderr.startswith("error: --hosts netns: could not create network namespaces")
    assert result.stderr.count("\n") == 1 and "Operation not permitted" in result.stderr, result.stderr
    assert not (tmp_path / "report").exists()
    assert [p for run, pids in _processes_of_run().items() if run not in before for p in pids] == []
    assert not [line for line in subprocess.run(["ip", "netns", "list"], capture_output=True, text=True).stdout
                .splitlines() if "tiling" in line]


@pytest.mark.skipif(not virtual_hosts_available(), reason=virtual_hosts_unavailable_reason())
def test_ctrl_c_with_hosts_removes_every_host_and_process(tmp_path: Path) -> None:
    """With --hosts netns, Ctrl-C in the middle of a trial leaves no node and no namespace keeper."""
    keepers_before = set(keeper_processes())
    def every_host_is_up() -> None:
        assert len(set(keeper_processes()) - keepers_before) >= 6  # hub, base, world, observer, robots, vi

    interrupt_a_run(tmp_path, "--hosts", "netns", "--link-loss", "5", "--link-rate", "5", nodes=8, running=3.0,
                    check_running=every_host_is_up)
    assert set(keeper_processes()) - keepers_before == set()
