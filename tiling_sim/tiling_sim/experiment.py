"""`experiment`: the paper's experiment in simulation (paper section 3), the product's main job.

    ros2 run tiling_sim experiment [--structure FILE] [--robots N] [--vi-robots N] [--trials N]
                                   [--removals N] [--misplacements N] [--wrong-tiles N]
                                   [--seed N] [--real-time-factor X] [--report DIR]

Every trial starts every node as its own OS process, exactly as on the robots (the simulated
world, the planner, the auction node, one assembly node per robot in /robotK, the inspection and
exploration nodes of the VI robot in /vi, or of each VI robot in /vi1, /vi2, ...), lets them build
the structure while the world removes tiles at random times (and, beyond the paper, lets chosen
placements land shifted, turned or as a tile of the wrong type, for the team to find and repair),
and stops them all. A first trial
without faults gives the makespan to compare with. At the end it prints the initial allocation
(Table 1), the allocation after detections of one trial (Table 2), the detection statistics beside
the paper's, the repairs of wrong placements, whether every trial finished the structure, and
makespans; and writes a report folder with pictures.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import shutil
import sys
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import rclpy
import yaml
from ament_index_python.packages import PackageNotFoundError, get_package_prefix, get_package_share_directory
from rclpy.executors import SingleThreadedExecutor

from tiling_assembly.interrupts import raise_if_signalled, raise_keyboard_interrupt_on_signals, signalled
from tiling_assembly.structure import StructureError
from tiling_assembly.structure_file import load_structure
from tiling_assembly.team import TeamFileError, TeamNode, TeamRole, load_team
from tiling_assembly.time_model import TimeModel
from tiling_ros.spinning import exit_unless_done_within
from tiling_sim import report
from tiling_sim.experiment_observer import ExperimentObserver
from tiling_sim.experiment_result import ExperimentConfig, ExperimentResult
from tiling_sim.network_plan import DEFAULT_NETNS_TIME_FACTOR, NetworkSettings, Outage
from tiling_sim.process_group import ProcessGroup
from tiling_sim.ros_domain import claim_domain_id, isolate
from tiling_sim.sim_settings import RobotBodySettings
from tiling_sim.team_network import TeamNetwork
from tiling_sim.trial_record import TrialRecord, detection_stats
from tiling_sim.virtual_hosts import VirtualHostsError

HEAVY_NODES = {"sim_vi", "vi_node", "vi_explorer"}  # ray casting, point clouds (the world is light: the clock)
ROS_SHUTDOWN_PATIENCE = 10.0  # s this process's own ROS teardown gets once every node has stopped


def is_heavy(process: str, vi_robots: list[str]) -> bool:
    """A VI robot's process (vi_node, viK_vi_node, viK_body, ...)."""
    return process in HEAVY_NODES or any(process.startswith(f"{vi}_") for vi in vi_robots)


@dataclass
class TrialSetup:
    trial: int
    seed: int
    removals: int
    faults: bool
    misplacements: int = 0  # placements that land shifted or turned
    wrong_tiles: int = 0  # placements of a tile of the wrong type


def executable(package: str, name: str) -> str:
    try:
        prefix = get_package_prefix(package)
    except PackageNotFoundError:
        raise RuntimeError(f"package {package} is not installed (build the workspace first)") from None
    path = Path(prefix) / "lib" / package / name
    if not path.exists():
        raise RuntimeError(f"{path} does not exist (build the workspace first)")
    return str(path)


def team_file(config_dir: Path) -> Path:
    """The --config folder's team.yaml, else the one installed with tiling_assembly (a folder of
    parameter files made before the team file existed)."""
    own = config_dir / "team.yaml"
    if own.exists():
        return own
    try:
        return Path(get_package_share_directory("tiling_assembly")) / "config" / "team.yaml"
    except PackageNotFoundError:
        raise RuntimeError("package tiling_assembly is not installed (build the workspace first)") from None


def process_name(role: TeamRole, robot: str, node: TeamNode, body: bool) -> str:
    """A process's name (and its log's): robotK for an assembly robot's node, robotK_body for its
    simulated body, else the executable's name."""
    if not robot:
        return node.executable
    return f"{robot}_body" if body else robot if len(role.nodes) == 1 else f"{robot}_{node.executable}"


def removals_per_trial(total: int, trials: int, seed: int) -> list[int]:
    """Spread `total` removals over `trials` as evenly as possible, extras on seeded trials."""
    if trials <= 0:
        return []
    counts = [total // trials] * trials
    extra = random.Random(seed).sample(range(trials), total % trials)
    for k in extra:
        counts[k] += 1
    return counts


def _write_events(logs: Path, record: TrialRecord) -> None:
    """The trial's world events, in simulated time, to `logs`/events.json."""
    events = [asdict(e) for e in sorted(record.events, key=lambda e: e.t)]
    logs.mkdir(parents=True, exist_ok=True)
    (logs / "events.json").write_text(json.dumps(events, indent=0) + "\n")


class Experiment:
    def __init__(self, config: ExperimentConfig, network: TeamNetwork | None = None) -> None:
        self.config = config
        self.network = network or TeamNetwork(config.network, config.robot_names, tuple(config.vi_robot_names))
        self.structure = load_structure(config.structure_file)
        self.finished: ExperimentResult | None = None  # the trials run so far, once `run` starts
        model = TimeModel()
        self.estimated_makespan = model.workload(self.structure, self.structure.tile_ids) / config.robots
        self.sim_limit = 6.0 * self.estimated_makespan + 300.0
        self.run_id = f"{os.getpid()}-{time.time_ns()}"  # marks every process of this run
        # each VI robot holds the clock for the scans its explorer waits for: more of them, slower runs
        # (pyramid_91 with 2 VI robots on 2 cores: 1.1x real time, a stop at every viewpoint)
        scanning = 1 + 3 * config.vi_robots
        self.wall_limit = config.wall_limit or self.sim_limit / config.real_time_factor * scanning + 60.0
        try:
            self.team = load_team(team_file(config.config_dir))
        except TeamFileError as error:
            raise RuntimeError(str(error)) from None
        self.sim_world = executable("tiling_sim", "sim_world")

    def params(self, *files: str) -> list[str]:
        """--params-file for each of `files` that config/ has."""
        paths = [self.config.config_dir / name for name in files]
        return [arg for path in paths if path.exists() for arg in ("--params-file", str(path))]

    def file_start_positions(self) -> list[float] | None:
        """The robots' start positions of the parameter file, when they fit the team."""
        path = self.config.config_dir / "tiling_sim.yaml"
        try:
            document = yaml.safe_load(path.read_text()) or {}
            starts = document["/**"]["ros__parameters"]["robot_start_xy"]
        except (OSError, yaml.YAMLError, KeyError, TypeError):
            starts = []
        fits = isinstance(starts, list) and len(starts) == 2 * self.config.robots
        return [float(v) for v in starts] if fits else None

    def start_positions_override(self) -> list[str]:
        """Robot start positions around the structure when the parameter file's do not fit the team."""
        return [] if self.file_start_positions() is not None else ["-p", "robot_start_xy:=[0.0]"]

    def start_positions(self) -> list[float]:
        """x1, y1, x2, y2, ...: where the simulated robots stand at the start (the planner is told)."""
        body = RobotBodySettings(robot_names=list(self.config.robot_names),
                                 robot_start_xy=self.file_start_positions() or [0.0])
        return [v for xy in body.robot_starts(self.structure).values() for v in xy]

    def computers(self) -> list[tuple[TeamRole, str]]:
        """Every computer of the team as (role, robot name; "" for the base station and a single VI
        robot, whose processes keep their plain names). Several VI robots take the team file's VI
        namespace with a number: /vi1, /vi2, ..."""
        vi = []
        if self.config.inspection:
            role, names = self.team["vi_robot"], self.config.vi_robot_names
            vi = [(role, "")] if len(names) == 1 else [(replace(role, namespace=name), name) for name in names]
        robots = [(self.team["assembly_robot"], robot) for robot in self.config.robot_names]
        return [(self.team["base_station"], ""), *vi, *robots]

    def node_commands(self, setup: TrialSetup) -> dict[str, list[str]]:
        """The command line of every process of a trial, by process name (the name of its log).

        The team's nodes are those of config/team.yaml, which the launch files read too: per role
        its nodes and, standing in for its hardware, its simulated body (`sim_robot` as process
        `robotK_body`, `sim_vi`), with the parameter files the team file names. The world
        (`sim_world`) is the one process only the simulation has.
        """
        commands = {"sim_world": self.world_command(setup)}
        for role, robot in self.computers():
            for node in role.nodes:
                commands[process_name(role, robot, node, body=False)] = self.team_node_command(role, robot, node)
            for body in role.simulated_by:
                name = process_name(role, robot, body, body=True)
                commands[name] = [*self.team_node_command(role, robot, body), *self.testbed_arguments(setup)]
                if self.config.record_scans and body.executable == "sim_vi":
                    commands[name] += ["-p", f"record_scans:={(self.trial_logs(setup) / (name + '_scans')).resolve()}"]
        return commands

    def trial_logs(self, setup: TrialSetup) -> Path:
        return self.config.report_dir / "logs" / f"trial_{setup.trial:02d}"

    def team_node_command(self, role: TeamRole, robot: str, node: TeamNode) -> list[str]:
        c = self.config
        namespace = role.namespace_of(robot)
        needs = {"structure_file": f"structure_file:={c.structure_file}",
                 "robot_names": f"robot_names:=[{', '.join(c.robot_names)}]"}
        command = [executable(node.package, node.executable), "--ros-args",
                   *(["-r", f"__ns:={namespace}"] if namespace else []), *self.params(*node.parameters),
                   *[arg for need in node.needs for arg in ("-p", needs[need])], "-p", "use_sim_time:=true"]
        if node.executable == "planner_node":
            command += ["-p", f"robot_start_xy:=[{', '.join(f'{v:.4f}' for v in self.start_positions())}]"]
        if node.executable == "auction_node" and not c.robots_find_missing:
            command += ["-p", "robots_find_missing:=false"]
        if node.executable == "assembly_node" and robot == c.silent_robot:
            command += ["-p", "bid_in_auctions:=false"]
        return command

    def testbed_arguments(self, setup: TrialSetup) -> list[str]:
        """What the simulated world and bodies share: the structure, the robots, the trial's seed."""
        c = self.config
        return ["-p", f"structure_file:={c.structure_file}", "-p", f"robot_names:=[{', '.join(c.robot_names)}]",
                "-p", f"vi_robot_names:=[{', '.join(c.vi_robot_names)}]",
                "-p", f"seed:={setup.seed}", *self.start_positions_override()]

    def world_command(self, setup: TrialSetup) -> list[str]:
        c = self.config
        window = (0.15 * self.estimated_makespan, 0.75 * self.estimated_makespan)
        return [self.sim_world, "--ros-args", *self.params("tiling_sim.yaml"), *self.testbed_arguments(setup),
                "-p", f"removals:={setup.removals}", "-p", f"misplacements:={setup.misplacements}",
                "-p", f"wrong_tiles:={setup.wrong_tiles}",
                "-p", f"removal_window_start:={window[0]:.1f}", "-p", f"removal_window_end:={window[1]:.1f}",
                "-p", f"real_time_factor:={c.real_time_factor}", "-p", "wait_for_start:=true",
                "-p", f"drop_probability:={c.drop_probability if setup.faults else 0.0}"]

    def expected_nodes(self) -> list[str]:
        team = [f"{role.namespace_of(robot)}/{node.executable}"
                for role, robot in self.computers() for node in (*role.nodes, *role.simulated_by)]
        return ["/sim_world", *team]

    def sensor_readers(self) -> list[tuple[str, str]]:
        """(topic, node): each VI robot's vi_node reading its camera and its overhead pose (see
        `ExperimentObserver.unread_sensors`)."""
        return [(f"{ns}/{topic}", f"{ns}/vi_node")
                for ns in self.vi_namespaces() for topic in ("camera/depth/points", "overhead_pose")]

    def vi_namespaces(self) -> list[str]:
        return [role.namespace_of(robot) for role, robot in self.computers()
                if any(node.executable == "vi_node" for node in role.nodes)]

    def run_trial(self, setup: TrialSetup, progress: str) -> TrialRecord:
        record = TrialRecord(trial=setup.trial, seed=setup.seed, removals_planned=setup.removals,
                             wrong_landings_planned=setup.misplacements + setup.wrong_tiles,
                             tile_types={i: t.type_name for i, t in self.structure.tiles.items()})
        logs = self.trial_logs(setup)
        if logs.exists():
            shutil.rmtree(logs)
        observer = ExperimentObserver(record, self.config.robot_names)
        executor = SingleThreadedExecutor()
        executor.add_node(observer)
        try:
            with ProcessGroup(log_dir=logs) as group:
                env = dict(os.environ, TILING_EXPERIMENT_RUN=self.run_id, PYTHONFAULTHANDLER="1")
                for name, argv in self.node_commands(setup).items():
                    # perception is throughput work: let coordination (auctions, robots) run first
                    group.start(name, self.network.command(name, argv), self.network.environment(name, env),
                                nice=10 if is_heavy(name, self.config.vi_robot_names) else 0)
                self.supervise(group, executor, observer, record, logs, progress)
                executor.remove_node(observer)
                observer.destroy_node()
                record.unclean_exits = group.stop()
                self.network.restore_links()
        finally:  # what happened is kept, a trial cut short by Ctrl-C too
            _write_events(logs, record)
        for name, code in record.unclean_exits.items():
            print(f"warning: trial {setup.trial}: {name} did not stop cleanly (exit code {code}); see "
                  f"{logs / (name + '.log')}", file=sys.stderr, flush=True)
        return record

    def supervise(self, group: ProcessGroup, executor: SingleThreadedExecutor, observer: ExperimentObserver,
                  record: TrialRecord, logs: Path, progress: str) -> None:
        """Follow the trial until it completes, a node dies or it runs out of time; start it once
        every node is up."""
        wall_start = time.monotonic()
        started_wall = None
        killed = False
        while True:
            executor.spin_once(timeout_sec=0.05)
            raise_if_signalled()  # a Ctrl-C that a binding swallowed, or turned into another error
            wall = time.monotonic() - wall_start
            dead = [n for n in group.dead() if n != self.config.kill_robot]
            if dead:
                ended = ", ".join(f"{name} {group.how_it_ended(name)}" for name in dead)
                record.failure = f"{ended} (see {logs})"
                return
            if started_wall is None:
                waiting = observer.ready_to_start(self.expected_nodes(), self.sensor_readers())
                if not waiting:
                    observer.start()
                    started_wall = time.monotonic()
                    record.started_at = 0.0
                elif wall > 60.0:
                    record.failure = f"the nodes did not come up within 60 s: waiting for {', '.join(waiting)}"
                    return
                continue
            now = observer.now()
            record.link_changes += self.network.follow_outages(now)
            placed = sum(1 for e in record.events if e.kind == "placed")
            removed = sum(1 for e in record.events if e.kind == "removed")
            out = f", link out: {', '.join(sorted(self.network.out))}" if self.network.out else ""
            self.show(f"{progress} t={now:6.0f} s simulated, {placed} placements, {removed} removals, "
                      f"{len(record.announcements)} auctions{out}")
            if self.config.kill_robot and not killed and placed >= self.config.kill_after_placements:
                group.kill(self.config.kill_robot)
                killed = True
            if observer.complete:
                return
            if now > self.sim_limit or time.monotonic() - started_wall > self.wall_limit:
                record.timed_out = True
                return

    def show(self, line: str) -> None:
        if not self.config.quiet and sys.stdout.isatty():
            print(f"\r{line[:110]:<110}", end="", flush=True)

    def run(self) -> ExperimentResult:
        c = self.config
        xy = self.start_positions()
        result = ExperimentResult(c, self.structure, robot_starts={
            robot: (xy[2 * k], xy[2 * k + 1]) for k, robot in enumerate(c.robot_names)})
        self.finished = result  # what an interruption keeps
        counts = removals_per_trial(c.removals, c.trials, c.seed)
        misplaced = removals_per_trial(c.misplacements, c.trials, c.seed + 1)
        wrong = removals_per_trial(c.wrong_tiles, c.trials, c.seed + 2)
        setups = ([TrialSetup(0, c.seed, 0, False)] if c.baseline else []) + [
            TrialSetup(k + 1, c.seed + k + 1, counts[k], True, misplaced[k], wrong[k]) for k in range(c.trials)
        ]
        for setup in setups:
            label = "baseline, no faults" if not setup.faults else f"{setup.removals} removal(s)"
            if setup.misplacements or setup.wrong_tiles:
                label += f", {setup.misplacements} misplaced, {setup.wrong_tiles} wrong tile(s)"
            progress = f"[trial {setup.trial}/{c.trials}] {label}:"
            wall = time.monotonic()
            record = self.run_trial(setup, progress)
            result.records.append(record)
            if not c.quiet:
                print(f"\r{progress} {trial_summary(record)} ({time.monotonic() - wall:.0f} s wall)".ljust(110),
                      flush=True)
        result.link_counters = self.network.counters()
        return result


def trial_summary(record: TrialRecord) -> str:
    if record.failure:
        return f"FAILED: {record.failure}"
    if record.timed_out:
        return "did not finish in time"
    stats = detection_stats(record)
    return (f"complete in {record.makespan():.0f} s simulated; removed {stats.removed}, "
            f"inspection said missing {stats.reported_missing}, found first by inspection {stats.detected} "
            f"/ by robots {stats.found_by_robot}, auctions {len(record.awards)}")


REPORTS = ExperimentConfig().report_dir.parent  # reports/<structure> by default


def parse_args(argv: list[str] | None) -> ExperimentConfig:
    parser = argparse.ArgumentParser(prog="experiment", description=__doc__.split("\n\n")[0])
    defaults = ExperimentConfig()
    parser.add_argument("--structure", default=str(defaults.structure_file), help="structure file")
    parser.add_argument("--robots", type=int, default=defaults.robots,
                        help=f"assembly robots (default {defaults.robots})")
    parser.add_argument("--vi-robots", type=int, default=defaults.vi_robots,
                        help=f"scanning (VI) robots: /vi for one, /vi1, /vi2, ... for more "
                        f"(default {defaults.vi_robots})")
    parser.add_argument("--trials", type=int, default=defaults.trials,
                        help=f"trials with faults (default {defaults.trials})")
    parser.add_argument("--removals", type=int, default=defaults.removals,
                        help=f"tiles removed over all trials (default {defaults.removals})")
    parser.add_argument("--misplacements", type=int, default=defaults.misplacements,
                        help="placements that land shifted 2-5 cm or turned 15-45 deg, over all trials "
                        f"(default {defaults.misplacements})")
    parser.add_argument("--wrong-tiles", type=int, default=defaults.wrong_tiles,
                        help="placements of a tile of the wrong type, over all trials "
                        f"(default {defaults.wrong_tiles})")
    parser.add_argument("--seed", type=int, default=defaults.seed,
                        help=f"seed of the whole experiment (default {defaults.seed})")
    parser.add_argument("--real-time-factor", type=float, default=None,
                        help=f"simulated / wall time (default {defaults.real_time_factor:g}; "
                        f"{DEFAULT_NETNS_TIME_FACTOR:g} with --hosts netns)")
    parser.add_argument("--drop-probability", type=float, default=defaults.drop_probability,
                        help="chance a tile slips when placed")
    parser.add_argument("--report", default=None, help=f"report folder (default {REPORTS}/<structure>)")
    parser.add_argument("--config", default=str(defaults.config_dir), help="folder of the nodes' parameter files")
    parser.add_argument("--no-baseline", action="store_true", help="skip the trial without faults")
    parser.add_argument("--kill-robot", default=defaults.kill_robot,
                        help="kill this robot's process after a few placements")
    parser.add_argument("--silent-robot", default=defaults.silent_robot,
                        help="this robot never bids (robustness check)")
    parser.add_argument("--no-inspection", action="store_true", help="build without the VI robot")
    parser.add_argument("--inspection-only", action="store_true",
                        help="only scans find missing tiles, as in the paper (robots do not report absent supports)")
    parser.add_argument("--quiet", action="store_true", help="no progress output")
    parser.add_argument("--wall-limit", type=float, default=defaults.wall_limit, metavar="SECONDS",
                        help="wall-clock seconds a trial may take before it counts as timed out (default: from the "
                        "structure's planned makespan, the time factor and the VI robots)")
    parser.add_argument("--record-scans", action="store_true",
                        help="write every VI robot's Kinect frames, true poses and truth to a rosbag2 in the trial's "
                        "logs (<vi robot>_scans, for `ros2 run vi_node classify`)")
    _add_network_options(parser)
    args = parser.parse_args(argv)
    structure = Path(args.structure)
    time_factor = args.real_time_factor or (DEFAULT_NETNS_TIME_FACTOR if args.hosts else defaults.real_time_factor)
    if args.vi_robots < 1:
        parser.error("--vi-robots must be >= 1 (--no-inspection builds without scanning)")
    if args.robots < 1 or args.trials < 0 or min(args.removals, args.misplacements, args.wrong_tiles) < 0 \
            or time_factor <= 0:
        parser.error("--robots must be >= 1, --trials, --removals, --misplacements and --wrong-tiles >= 0, "
                     "--real-time-factor > 0")
    if args.wall_limit < 0:
        parser.error("--wall-limit must be >= 0 (0: from the structure)")
    if not Path(args.config).is_dir():
        parser.error(f"--config {args.config}: no such folder of parameter files")
    network = _network(parser, args)
    return ExperimentConfig(
        structure_file=structure.resolve(), robots=args.robots, vi_robots=args.vi_robots, trials=args.trials,
        removals=args.removals,
        misplacements=args.misplacements, wrong_tiles=args.wrong_tiles,
        seed=args.seed, real_time_factor=time_factor, network=network,
        report_dir=Path(args.report or f"{REPORTS}/{structure.stem}"), config_dir=Path(args.config).resolve(),
        baseline=not args.no_baseline, drop_probability=args.drop_probability, kill_robot=args.kill_robot,
        silent_robot=args.silent_robot, quiet=args.quiet, inspection=not args.no_inspection,
        robots_find_missing=not args.inspection_only, record_scans=args.record_scans, wall_limit=args.wall_limit,
    )


def _add_network_options(parser: argparse.ArgumentParser) -> None:
    defaults = NetworkSettings()
    parser.add_argument("--hosts", choices=["netns"], default=defaults.hosts,
                        help="netns: every robot, the base station and the world on a host of its own (needs root)")
    parser.add_argument("--link-loss", type=float, default=defaults.loss_percent, metavar="PCT",
                        help="robots' links drop PCT%% of frames")
    parser.add_argument("--link-rate", type=float, default=defaults.rate_mbit, metavar="MBIT",
                        help="robots' links carry MBIT Mbit/s")
    parser.add_argument("--link-delay", type=float, default=defaults.delay_ms, metavar="MS",
                        help="robots' links delay frames MS ms")
    parser.add_argument("--link-outage", action="append", default=[], metavar="ROBOT:AT:SECONDS",
                        help="cut ROBOT's link at AT s of simulated time for SECONDS (repeatable)")


def _network(parser: argparse.ArgumentParser, args: argparse.Namespace) -> NetworkSettings:
    """The network options, checked against the team (one line and exit 2 when they do not fit)."""
    robots = [f"robot{k + 1}" for k in range(args.robots)]
    try:
        network = NetworkSettings(args.hosts, args.link_loss, args.link_rate, args.link_delay,
                                  tuple(Outage.parse(text) for text in args.link_outage))
        network.check(robots, ExperimentConfig(vi_robots=args.vi_robots).vi_robot_names)
        TeamNetwork.link_shape(network)  # checks the link's numbers
    except ValueError as error:
        parser.error(str(error))
    return network


def main(argv: list[str] | None = None) -> int:
    config = parse_args(argv)
    raise_keyboard_interrupt_on_signals()  # also SIGTERM; both recorded in `signalled`
    domain, _lock = claim_domain_id()
    isolate(domain)
    network = None
    code = 2
    try:
        network = TeamNetwork.build(config.network, config.robot_names, f"{os.getpid()}",
                                    dds_profile=str(config.config_dir / "fastdds_wifi.xml"),
                                    vi_robots=config.vi_robot_names)
        rclpy.init(args=None)
        code = run_experiment(config, network, domain)
    except StructureError as error:
        print(f"error: {error}", file=sys.stderr)
    except VirtualHostsError as error:
        print(f"error: --hosts netns: {error}", file=sys.stderr)
    except RuntimeError as error:
        if signalled.is_set():  # the Ctrl-C itself: pybind11 turns a KeyboardInterrupt raised while it
            code = _interrupted()  # converts a call's arguments into "Unable to convert call argument"
        else:
            print(f"error: {error}", file=sys.stderr)
    except KeyboardInterrupt:
        code = _interrupted()
    finally:
        if network is not None:
            network.close()
        # a node killed mid-message can leave a Fast DDS shared-memory port locked for good: this
        # process's own teardown then blocks on it (seen after stopping 8 robots and 2 VI robots)
        with exit_unless_done_within(ROS_SHUTDOWN_PATIENCE, f"experiment: ROS did not shut down within "
                                     f"{ROS_SHUTDOWN_PATIENCE:g} s; exiting without it", exit_code=code):
            rclpy.try_shutdown()
    return code


def run_experiment(config: ExperimentConfig, network: TeamNetwork, domain: int) -> int:
    """The trials and their report; the exit code (0: every trial completed)."""
    experiment = Experiment(config, network)
    config.report_dir.mkdir(parents=True, exist_ok=True)
    print(report.header(config, experiment.structure), flush=True)
    if not config.quiet and network.hosts is None:
        print(f"ROS_DOMAIN_ID={domain} (private, this host only); watch with: ROS_DOMAIN_ID={domain} "
              "ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST ros2 topic echo /auction/decisions", flush=True)
    elif not config.quiet:
        print(network.describe(), flush=True)
    try:
        result = experiment.run()
    except (KeyboardInterrupt, RuntimeError):
        if not signalled.is_set():
            raise
        return _interrupted(kept=_keep_finished_trials(experiment))
    print(report.summary_text(result), flush=True)
    path = report.write(result)
    print(f"Report: {path}")
    return 0 if all(r.complete() for r in result.records) else 1


def _keep_finished_trials(experiment: Experiment) -> str:
    """Writes an interrupted run's report of the trials it finished (an hour of trials is not lost
    to a Ctrl-C in the last one); says where it is, or "" if no trial had finished."""
    finished = experiment.finished
    if finished is None or not finished.records:
        return ""
    finished.interrupted = True
    path = report.write(finished)
    return f"the {len(finished.records)} trial(s) finished before are in {path}"


def _interrupted(kept: str = "") -> int:
    print(f"\ninterrupted: every node was stopped{'; ' + kept if kept else ''}", file=sys.stderr, flush=True)
    return 130


if __name__ == "__main__":
    os.environ.setdefault("RCUTILS_LOGGING_USE_STDOUT", "0")
    sys.exit(main())
