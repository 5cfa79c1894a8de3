#!/usr/bin/env python3
"""Signal every node executable at a random moment and check that it stops cleanly.

`ros2 launch` stops its nodes by sending SIGINT (then SIGTERM) to each node's process alone, at
whatever moment the user presses Ctrl-C: during the imports, while rclpy starts, while a driver
waits for its port or the assembly node for /plan, in the middle of a callback. This harness does
the same without launch: it starts a node's executable as `ros2 run` would (the installed
`lib/<package>/<executable>`, with the environment of the workspace), waits a random delay, sends
SIGINT or SIGTERM to that pid alone and waits for the exit. A trial fails when the process exits
with a code other than 0, prints a traceback, "terminate called" or other shutdown noise, leaves
processes behind, or is still running `exit_timeout` seconds after the signal (its Python stacks
are then dumped into its log). A failure is "too early" rather than failed when the process had
no SIGTERM handler of its own yet: the interpreter and the script setuptools generates were still
starting (~50-300 ms), before any code of this project can catch a signal.

    tools/workspace-env python tools/signal_trials.py [--trials N [--per-executable]] [--max-delay S]
        [--startup-share F] [--parallel K] [--load | --load-share F] [--only NAME[,NAME...]]
        [--seed N] [--log-dir DIR] [--results FILE] [--list]

Every trial runs in a private ROS domain on this host (tiling_sim.ros_domain). Device emulators
on pseudo-terminals stand in for the robots' hardware; a recorded bag replayed in a loop keeps
vi_node inspecting; tools/keep_navigating.py keeps the base navigator driving; a simulated
one-robot team keeps the assembly node, its body and the world building. `--load` runs every
trial with one busy-loop process per core; `--load-share` runs that share of each scenario's
trials so, after the others. No ROS import here: the harness only starts processes and reads
their logs.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import random
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from pathlib import Path

from tiling_sim.ros_domain import claim_domain_id  # ROS-free: a lock file per domain id

REPO = Path(__file__).resolve().parent.parent
STRUCTURE = str(REPO / "config" / "structures" / "paper_14.yaml")
BAG = str(REPO / "tests" / "data" / "vi_scans" / "paper_qvga")
NOISE = ("Traceback", "terminate called", "Fatal Python error", "Segmentation fault", "Exception ignored",
         "never awaited", "never retrieved")
TARGET_MARK = "SIGNAL_TRIAL_TARGET"  # in the target's environment, inherited by whatever it starts
TRIAL_DIR = "{trial_dir}"  # replaced in every argument by the trial's own folder (ports, reports)


def params_file(name: str) -> tuple[str, str]:
    return "--params-file", str(REPO / "config" / f"{name}.yaml")


@dataclass(frozen=True)
class Command:
    """An installed executable and its arguments, as `ros2 run PACKAGE EXECUTABLE ARGS` runs it."""

    package: str
    executable: str
    arguments: tuple[str, ...] = ()

    def argv(self, trial_dir: Path) -> list[str]:
        arguments = [a.replace(TRIAL_DIR, str(trial_dir)) for a in self.arguments]
        if not self.package:  # a script of this repository
            return [sys.executable, str(REPO / self.executable), *arguments]
        return [str(executable_path(self.package, self.executable)), *arguments]


@dataclass(frozen=True)
class Helper:
    """A process the target needs (a device emulator, a bag replayer, another node); never signalled
    by the trial. `ready_text`: wait until its output shows this; `restart`: start it again whenever
    it exits, so that the target keeps getting work for the whole trial; `forbidden_after_stop`: what
    it must not have said once stopped after the target (how a target that did not stop its work
    shows)."""

    name: str
    command: Command
    ready_text: str | None = None
    restart: bool = False
    forbidden_after_stop: str | None = None  # in its log once it stopped: the target failed


@dataclass(frozen=True)
class Scenario:
    """One executable brought to one realistic state: its command line and the helpers it needs.

    `startup_span`: about how long (s) it takes to reach its steady state; start-up-biased delays
    fall within it. `clean_exit_codes`: what a clean stop exits with (a command-line tool that
    reports an interruption may exit 130). `extra_noise`: log texts that are failures for it."""

    name: str
    target: Command
    helpers: tuple[Helper, ...] = ()
    startup_span: float = 3.0
    clean_exit_codes: tuple[int, ...] = (0,)
    extra_noise: tuple[str, ...] = ()
    may_finish_first: bool = False  # a command-line tool whose work can end before the signal comes

    @property
    def executable(self) -> str:
        return self.target.executable


def node(package: str, executable: str, *arguments: str) -> Command:
    return Command(package, executable, ("--ros-args", *arguments))


def emulator(kind: str, *arguments: str) -> Helper:
    command = Command("hardware_drivers", f"{kind}_emulator", ("--port", f"{TRIAL_DIR}/{kind}", *arguments))
    return Helper(f"{kind}_emulator", command, ready_text="ready")


def driver(executable: str, port: str, *arguments: str) -> Command:
    return node("hardware_drivers", executable, "-r", "__ns:=/robot1", *params_file("hardware_drivers"),
                "-p", f"port:={port}", *arguments)


def scenarios() -> list[Scenario]:
    """Every node executable the packages install, each in the states a user meets it in: waiting
    for its inputs, without its device, at work."""
    missing_port = f"{TRIAL_DIR}/no_device"
    planner = Helper("planner_node", planner_node())
    replayer = Helper("replay_bag", Command("tiling_sim", "replay_bag", (
        "--bag", BAG, "--rate", "0", "--gap", "0.3", "--wait-subscribers", "60", "--linger", "0.2")),
        restart=True)
    navigating = Helper("keep_navigating", Command("", "tools/keep_navigating.py", ("--namespace", "/robot1")),
                        forbidden_after_stop="last cmd_vel: moving")
    base = (emulator("create"), Helper("create_base", driver("create_base", f"{TRIAL_DIR}/create")))
    return [
        Scenario("planner_node", planner_node()),
        Scenario("auction_node", auction_node()),
        Scenario("auction_node (with a plan)", auction_node(), helpers=(planner,)),
        Scenario("assembly_node", assembly_node()),
        Scenario("assembly_node (with a plan)", assembly_node(), helpers=(planner,)),
        Scenario("assembly_node (building)", assembly_node(*SIM_TIME),
                 helpers=team_helpers("world", "planner", "body"), startup_span=6.0),
        Scenario("vi_node", vi_node(), startup_span=6.0),
        Scenario("vi_node (inspecting)", vi_node(), helpers=(replayer,), startup_span=6.0),
        Scenario("vi_explorer", node("vi_node", "vi_explorer", "-r", "__ns:=/vi", *params_file("vi_node"),
                                     "-p", STRUCTURE_PARAMETER)),
        Scenario("sim_world", sim_world("wait_for_start:=true"), startup_span=6.0),
        Scenario("sim_world (building)", sim_world("wait_for_start:=false"),
                 helpers=team_helpers("planner", "body", "assembly"), startup_span=6.0),
        Scenario("sim_robot", sim_robot()),
        Scenario("sim_robot (building)", sim_robot(), helpers=team_helpers("world", "planner", "assembly"),
                 startup_span=6.0),
        Scenario("sim_vi", sim_vi(), startup_span=6.0),
        Scenario("create_base", driver("create_base", f"{TRIAL_DIR}/create"), helpers=(emulator("create"),)),
        Scenario("create_base (no device)", driver("create_base", missing_port)),
        Scenario("crustcrawler_arm", driver("crustcrawler_arm", f"{TRIAL_DIR}/dynamixel", *ARM),
                 helpers=(emulator("dynamixel"),)),
        Scenario("crustcrawler_arm (no device)", driver("crustcrawler_arm", missing_port, *ARM)),
        Scenario("hokuyo_urg", driver("hokuyo_urg", f"{TRIAL_DIR}/urg"), helpers=(emulator("urg"),)),
        Scenario("hokuyo_urg (no device)", driver("hokuyo_urg", missing_port)),
        Scenario("m3_robot", m3_robot()),
        Scenario("m3_robot (placing)", m3_robot(*FAST_M3), helpers=m3_robot_body(), startup_span=6.0),
        Scenario("base_navigator", node("hardware_drivers", "base_navigator", "-r", "__ns:=/vi",
                                        *params_file("hardware_drivers"))),
        Scenario("base_navigator (driving)", node("hardware_drivers", "base_navigator", "-r", "__ns:=/robot1",
                                                  *params_file("hardware_drivers")), helpers=(*base, navigating)),
        *command_line_tools(),
        Scenario("experiment", Command("tiling_sim", "experiment", (
            "--trials", "1", "--removals", "1", "--no-baseline", "--quiet", "--report", f"{TRIAL_DIR}/report")),
            startup_span=10.0, clean_exit_codes=(0, 130), extra_noise=("did not stop cleanly",)),
    ]


def command_line_tools() -> list[Scenario]:
    """The offline tools a user runs by hand and stops with Ctrl-C: an interruption exits 130 (0 for
    the device emulators, which stand in for hardware); a short tool may finish first."""
    def tool(name: str, package: str, executable: str, *arguments: str, quick: bool = False) -> Scenario:
        return Scenario(name, Command(package, executable, arguments), clean_exit_codes=(0, 130),
                        startup_span=2.0, may_finish_first=quick)

    return [
        tool("plan", "planner_node", "plan", "--structure", STRUCTURE, "--robots", "2", quick=True),
        tool("benchmark", "planner_node", "benchmark", "--sizes", "200", "2000", "--repeat", "3"),
        tool("validate", "tiling_assembly", "validate", STRUCTURE, quick=True),
        tool("classify", "vi_node", "classify", "--structure", STRUCTURE, "--bag", BAG, quick=True),
        tool("replay_bag (waiting for a subscriber)", "tiling_sim", "replay_bag", "--bag", BAG,
             "--wait-subscribers", "60"),
        tool("vi_accuracy", "tiling_sim", "vi_accuracy", "--scenes", "40", "--png", f"{TRIAL_DIR}/accuracy.png"),
        # 20 repeats run well past the latest signal (6 s); 5 took 6.3 s on a quiet machine and raced it
        tool("vi_benchmark", "tiling_sim", "vi_benchmark", "--scans", "4", "--repeat", "20"),
        *(Scenario(f"{kind}_emulator", Command("hardware_drivers", f"{kind}_emulator",
                                               ("--port", f"{TRIAL_DIR}/{kind}")), startup_span=2.0)
          for kind in ("create", "dynamixel", "urg")),
    ]


# -- the command lines (as config/team.yaml and the experiment runner give them)

STRUCTURE_PARAMETER = f"structure_file:={STRUCTURE}"
TEAM_PARAMETER = "robot_names:=[robot1, robot2]"
SIM_TIME = ("-p", "use_sim_time:=true")
ARM = params_file("crustcrawler_arm")
# a one-robot team builds the whole structure itself (no support waits on a robot that is not there)
BUILDING_TEAM = ("-p", f"structure_file:={STRUCTURE}", "-p", "robot_names:=[robot1]", "-p", "seed:=1",
                 "-p", "robot_start_xy:=[0.0]")


def planner_node(*arguments: str) -> Command:
    return node("planner_node", "planner_node", *params_file("planner_node"), "-p", STRUCTURE_PARAMETER,
                "-p", TEAM_PARAMETER, *arguments)


def auction_node(*arguments: str) -> Command:
    return node("auction_node", "auction_node", *params_file("auction_node"), *arguments)


def assembly_node(*arguments: str) -> Command:
    return node("assembly_node", "assembly_node", "-r", "__ns:=/robot1", *params_file("assembly_node"),
                "-p", STRUCTURE_PARAMETER, *arguments)


def vi_node(*arguments: str) -> Command:
    return node("vi_node", "vi_node", "-r", "__ns:=/vi", *params_file("vi_node"), "-p", STRUCTURE_PARAMETER,
                *arguments)


def sim_world(wait_for_start: str) -> Command:
    return node("tiling_sim", "sim_world", *params_file("tiling_sim"), *BUILDING_TEAM, "-p", wait_for_start)


def sim_robot() -> Command:
    return node("tiling_sim", "sim_robot", "-r", "__ns:=/robot1", *params_file("tiling_sim"), *BUILDING_TEAM,
                *SIM_TIME)


def sim_vi() -> Command:
    return node("tiling_sim", "sim_vi", "-r", "__ns:=/vi", *params_file("vi_node"), *params_file("tiling_sim"),
                *BUILDING_TEAM, *SIM_TIME)


def m3_robot(*arguments: str) -> Command:
    return node("hardware_drivers", "m3_robot", "-r", "__ns:=/robot1", *params_file("hardware_drivers"), *ARM,
                "-p", STRUCTURE_PARAMETER, *arguments)


# as tests/drivers/test_m3_robot.py: quicker servos and base than the real robot's, a tile at the cache
FAST_SERVOS = ("-p", "joint_max_velocities:=[3.0,3.0,3.0,3.0,3.0,3.0]")
FAST_M3 = (*FAST_SERVOS, "-p", "arm_speed:=2.5", "-p", "max_linear:=0.3", "-p", "max_angular:=1.5",
           "-p", "laser_mount:=[0.16,0.0,0.0]")


def m3_robot_body() -> tuple[Helper, ...]:
    """The M3 robot's devices (emulated), their drivers, and tools/keep_placing.py sending missions."""
    pose_file = f"{TRIAL_DIR}/true_pose"
    return (
        emulator("create", "--pose-file", pose_file, "--start-pose", "0.0,-0.45,0.3"),
        emulator("dynamixel", "--stall", "6:473"),  # the gripper servo stops on a 4 cm tile
        emulator("urg", "--robot-pose-file", pose_file, "--laser-mount", "0.16,0.0,0.0",
                 "--tile-pose", "0.02,-1.01,0.4"),
        Helper("create_base", driver("create_base", f"{TRIAL_DIR}/create")),
        Helper("crustcrawler_arm", driver("crustcrawler_arm", f"{TRIAL_DIR}/dynamixel", *ARM, *FAST_SERVOS)),
        Helper("hokuyo_urg", driver("hokuyo_urg", f"{TRIAL_DIR}/urg")),
        Helper("keep_placing", Command("", "tools/keep_placing.py", ("--pose-file", pose_file)),
               forbidden_after_stop="last cmd_vel: moving"),
    )


def team_helpers(*members: str) -> tuple[Helper, ...]:
    """The simulated team around a target that is building: the world (running), the planner of a
    one-robot team, robot1's body and its assembly node."""
    every = {
        "world": Helper("sim_world", sim_world("wait_for_start:=false")),
        "planner": Helper("planner_node", node("planner_node", "planner_node", *params_file("planner_node"),
                                               *BUILDING_TEAM, *SIM_TIME)),
        "body": Helper("sim_robot", sim_robot()),
        "assembly": Helper("assembly_node", assembly_node(*SIM_TIME)),
    }
    return tuple(every[member] for member in members)


@dataclass(frozen=True)
class TrialSettings:
    trials: int = 10  # per scenario
    per_executable: bool = False  # `trials` per executable instead, shared out among its scenarios
    max_delay: float = 20.0  # s, longest wait before the signal
    startup_share: float = 0.3  # of the trials signalled within the scenario's start-up span
    parallel: int = 2  # trials at once
    load_share: float = 0.0  # of the trials run with a busy-loop process on every core
    twice_share: float = 0.0  # of the trials that signal twice, 0-0.5 s apart (Ctrl-C pressed twice)
    only: tuple[str, ...] = ()  # scenario or executable names; empty: all
    seed: int = 1
    exit_timeout: float = 10.0  # s after the signal
    log_dir: Path = field(default_factory=lambda: Path(tempfile.gettempdir()) / "signal_trials")


@dataclass(frozen=True)
class TrialPlan:
    scenario: Scenario
    number: int
    signal: signal.Signals
    delay: float
    under_load: bool
    again_after: float | None = None  # s after the first signal, the same signal once more

    @property
    def label(self) -> str:
        again = f" and again {self.again_after:.2f} s later" if self.again_after is not None else ""
        return f"{self.scenario.name} #{self.number} {self.signal.name} at {self.delay:.2f} s{again}"


@dataclass(frozen=True)
class TrialResult:
    plan: TrialPlan
    exit_code: int | None
    stop_seconds: float | None  # from the signal to the exit
    failure: str | None  # None: a clean stop
    log_path: Path
    caught_signals: bool = True  # the process had its own handlers in place when signalled

    @property
    def outcome(self) -> str:
        """clean, finished first (a tool done before the signal, cleanly), failed, or too early: failed,
        but signalled before the process could catch signals (the interpreter or the script setuptools
        generates was still starting: no code of ours ran)."""
        if self.failure is None:
            return "clean" if self.stop_seconds is not None or not self.plan.scenario.may_finish_first \
                else "finished first"
        return "failed" if self.caught_signals else "too early"


# -- locating executables (as `ros2 run` does: the ament index on AMENT_PREFIX_PATH)

def executable_path(package: str, name: str) -> Path:
    for prefix in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep):
        if prefix and (Path(prefix) / "share/ament_index/resource_index/packages" / package).exists():
            path = Path(prefix) / "lib" / package / name
            if path.exists():
                return path
    raise RuntimeError(f"no executable {name} in package {package} on AMENT_PREFIX_PATH "
                       "(build the workspace and run this under tools/workspace-env)")


def selected(all_scenarios: Sequence[Scenario], only: Sequence[str]) -> list[Scenario]:
    if not only:
        return list(all_scenarios)
    chosen = [s for s in all_scenarios if s.name in only or s.executable in only]
    unknown = [name for name in only if not any(name in (s.name, s.executable) for s in all_scenarios)]
    if unknown:
        raise ValueError(f"no scenario or executable named {', '.join(unknown)}")
    return chosen


# -- planning: which signal, when, under load or not

def plan_trials(settings: TrialSettings, chosen: Sequence[Scenario]) -> list[TrialPlan]:
    """Each scenario's trials: SIGINT and SIGTERM in equal shares, delays drawn from the seed; the
    load share of each scenario last. Scenarios interleave so that parallel trials differ."""
    rng = random.Random(settings.seed)
    per_scenario = [scenario_plans(rng, settings, scenario, trials_of(settings, scenario, chosen))
                    for scenario in chosen]
    longest = max((len(plans) for plans in per_scenario), default=0)
    interleaved = [plans[k] for k in range(longest) for plans in per_scenario if k < len(plans)]
    return sorted(interleaved, key=lambda p: p.under_load)  # stable: the loaded phase after the other


def trials_of(settings: TrialSettings, scenario: Scenario, chosen: Sequence[Scenario]) -> int:
    """`settings.trials` per scenario, or per executable shared out among its scenarios."""
    if not settings.per_executable:
        return settings.trials
    siblings = sum(s.executable == scenario.executable for s in chosen)
    return math.ceil(settings.trials / siblings)


def scenario_plans(rng: random.Random, settings: TrialSettings, scenario: Scenario, trials: int) -> list[TrialPlan]:
    signals = ([signal.SIGINT, signal.SIGTERM] * (trials // 2 + 1))[:trials]
    rng.shuffle(signals)
    loaded_from = trials - round(trials * settings.load_share)
    return [TrialPlan(scenario, k + 1, signals[k], draw_delay(rng, settings, scenario), k >= loaded_from,
                      rng.uniform(0.0, 0.5) if rng.random() < settings.twice_share else None)
            for k in range(trials)]


def draw_delay(rng: random.Random, settings: TrialSettings, scenario: Scenario) -> float:
    if rng.random() < settings.startup_share:
        return rng.uniform(0.0, min(scenario.startup_span, settings.max_delay))
    return rng.uniform(0.0, settings.max_delay)


# -- processes

_live: set[subprocess.Popen[bytes]] = set()  # every process a trial started, for Ctrl-C of the harness
_live_lock = threading.Lock()


def start_process(argv: list[str], env: dict[str, str], log_path: Path) -> subprocess.Popen[bytes]:
    """A process in a session of its own, as launch's nodes are detached from our terminal: only the
    trial's own signal reaches it."""
    with open(log_path, "ab") as log:
        process = subprocess.Popen(argv, stdin=subprocess.DEVNULL, stdout=log, stderr=subprocess.STDOUT,
                                   env=env, cwd=REPO, start_new_session=True)
    with _live_lock:
        _live.add(process)
    return process


def kill_session(process: subprocess.Popen[bytes]) -> None:
    try:
        os.killpg(process.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass
    process.wait()
    with _live_lock:
        _live.discard(process)


def stop_politely(process: subprocess.Popen[bytes], grace: float = 5.0) -> None:
    if process.poll() is None:
        try:
            os.killpg(process.pid, signal.SIGINT)
            process.wait(grace)
        except (ProcessLookupError, PermissionError, subprocess.TimeoutExpired):
            pass
    kill_session(process)


def kill_everything_started() -> None:
    with _live_lock:
        processes = list(_live)
    for process in processes:
        kill_session(process)


class RunningHelper:
    """A helper process for the length of one trial (restarted when it exits, if it asks for it)."""

    def __init__(self, helper: Helper, argv: list[str], env: dict[str, str], log_path: Path) -> None:
        self.helper, self.argv, self.env, self.log_path = helper, argv, env, log_path
        self.process = start_process(argv, env, log_path)
        self._stopping = threading.Event()
        self._watcher: threading.Thread | None = None
        if helper.restart:
            self._watcher = threading.Thread(target=self._keep_running, daemon=True)
            self._watcher.start()

    def _keep_running(self) -> None:
        while not self._stopping.wait(0.1):
            if self.process.poll() is not None:
                kill_session(self.process)
                self.process = start_process(self.argv, self.env, self.log_path)

    def wait_ready(self, timeout: float = 60.0) -> None:
        text = self.helper.ready_text
        deadline = time.monotonic() + timeout
        while text is not None and text not in self.log_path.read_text(errors="replace"):
            if self.process.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError(f"helper {self.helper.name} did not print '{text}' (see {self.log_path})")
            time.sleep(0.05)

    def stop(self) -> None:
        self._stopping.set()
        if self._watcher is not None:
            self._watcher.join()
        stop_politely(self.process)

    def complaint(self) -> str | None:
        """What the helper saw the target fail to do, once the helper stopped."""
        text = self.helper.forbidden_after_stop
        if text is None:
            return None
        lines = self.log_path.read_text(errors="replace").splitlines()
        said = next((line.strip() for line in lines if text in line), None)
        return f"{self.helper.name} says: {said}" if said is not None else None


@contextmanager
def private_ros_domain() -> Iterator[dict[str, str]]:
    """Environment variables of a ROS domain id no other run on this host holds, for one trial."""
    domain, lock = claim_domain_id()
    try:
        yield {"ROS_DOMAIN_ID": str(domain), "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    finally:
        lock.close()


@contextmanager
def cpu_hogs(count: int) -> Iterator[None]:
    """One busy loop per core, for trials under CPU load."""
    hogs = [subprocess.Popen([sys.executable, "-S", "-c", "while True: pass"]) for _ in range(count)]
    try:
        yield
    finally:
        for hog in hogs:
            hog.kill()
            hog.wait()


# -- one trial

def run_trial(plan: TrialPlan, settings: TrialSettings) -> TrialResult:
    name = f"{slug(plan.scenario.name)}_{plan.number:03d}_{plan.signal.name}"
    trial_dir = Path(tempfile.mkdtemp(prefix=f"{name}_", dir=settings.log_dir))
    log_path = trial_dir / "target.log"
    with private_ros_domain() as domain:
        env = {**os.environ, **domain, "PYTHONUNBUFFERED": "1"}
        helpers = [RunningHelper(h, h.command.argv(trial_dir), env, trial_dir / f"{h.name}.log")
                   for h in plan.scenario.helpers]
        try:
            for helper in helpers:
                helper.wait_ready()
            target_env = {**env, TARGET_MARK: str(trial_dir), "PYTHONFAULTHANDLER": "1"}
            target = start_process(plan.scenario.target.argv(trial_dir), target_env, log_path)
            result = signal_and_judge(plan, settings, target, log_path)
        finally:
            for helper in reversed(helpers):
                helper.stop()
    complaint = next(filter(None, (helper.complaint() for helper in helpers)), None)
    if result.failure is None and complaint is not None:
        return replace(result, failure=complaint)
    return result


def signal_and_judge(plan: TrialPlan, settings: TrialSettings, target: subprocess.Popen[bytes],
                     log_path: Path) -> TrialResult:
    try:
        target.wait(plan.delay)
        code = target.returncode
        if plan.scenario.may_finish_first:
            return TrialResult(plan, code, None, judge_exit(plan.scenario, code, log_path), log_path)
        return TrialResult(plan, code, None, f"exited by itself (code {code}) before the signal: "
                           f"{last_line(log_path)}", log_path)
    except subprocess.TimeoutExpired:
        pass
    caught = catches_sigterm(target.pid)
    os.kill(target.pid, plan.signal)  # that process alone, as launch does
    signalled = time.monotonic()
    try:
        if plan.again_after is not None:
            signal_again_if_running(target, plan)
        code = target.wait(max(0.0, settings.exit_timeout - (time.monotonic() - signalled)))
    except subprocess.TimeoutExpired:
        dump_stacks_and_kill(target)
        return TrialResult(plan, None, None, f"still running {settings.exit_timeout:g} s after "
                           f"{plan.signal.name}: {last_line(log_path)}", log_path, caught)
    stop_seconds = time.monotonic() - signalled
    kill_session(target)  # anything left in its session
    failure = judge_exit(plan.scenario, code, log_path) or leftovers(log_path.parent)
    return TrialResult(plan, code, stop_seconds, failure, log_path, caught)


def signal_again_if_running(target: subprocess.Popen[bytes], plan: TrialPlan) -> None:
    """A node can be signalled again while it stops: Ctrl-C pressed twice, launch's SIGTERM once its
    `sigterm_timeout` is over, or the SIGINT of a non-interactive launch besides its group's."""
    assert plan.again_after is not None
    try:
        target.wait(plan.again_after)
    except subprocess.TimeoutExpired:
        os.kill(target.pid, plan.signal)


def dump_stacks_and_kill(process: subprocess.Popen[bytes]) -> None:
    """SIGABRT first: the target runs with PYTHONFAULTHANDLER set, so its log gets every thread's
    Python stack, where it hangs."""
    try:
        os.kill(process.pid, signal.SIGABRT)
        process.wait(3.0)
    except (ProcessLookupError, subprocess.TimeoutExpired):
        pass
    kill_session(process)


def catches_sigterm(pid: int) -> bool:
    """Whether the process has a handler of its own for SIGTERM (Python catches SIGINT from its very
    start, SIGTERM only once a program asks: `tiling_assembly.interrupts` sets both together)."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return False
    caught = next((line.split()[1] for line in status.splitlines() if line.startswith("SigCgt:")), "0")
    return bool(int(caught, 16) & (1 << (signal.SIGTERM - 1)))


def judge_exit(scenario: Scenario, code: int, log_path: Path) -> str | None:
    lines = log_path.read_text(errors="replace").splitlines()
    for k, line in enumerate(lines):
        if any(marker in line for marker in (*NOISE, *scenario.extra_noise)):
            return f"exit code {code}: {line.strip()}{exception_after(lines, k)}"
    if code not in scenario.clean_exit_codes:
        return f"exit code {code}: {last_line(log_path)}"
    return None


def exception_after(lines: Sequence[str], start: int) -> str:
    """' ... <the exception>' when lines[start] opens a traceback: the first unindented line after it
    says what was raised, and where is in the indented line above that."""
    if not lines[start].startswith("Traceback"):
        return ""
    for k in range(start + 1, len(lines)):
        if lines[k] and not lines[k].startswith(" "):
            where = lines[k - 2].strip() if k >= 2 and lines[k - 2].startswith("  File") else ""
            return f" ... {where} ... {lines[k].strip()}"
    return ""


def leftovers(trial_dir: Path, grace: float = 5.0) -> str | None:
    """A failure if processes the target started are still alive `grace` s after it exited."""
    mark = f"{TARGET_MARK}={trial_dir}".encode()
    deadline = time.monotonic() + grace
    while True:
        alive = [pid for pid in marked_processes(mark)]
        if not alive:
            return None
        if time.monotonic() > deadline:
            for pid in alive:
                try:
                    os.kill(pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
            return f"left {len(alive)} process(es) running: {', '.join(command_line(p) for p in alive)}"
        time.sleep(0.1)


def marked_processes(mark: bytes) -> list[int]:
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            if mark in (entry / "environ").read_bytes().split(b"\0"):
                found.append(int(entry.name))
        except OSError:
            continue  # exited meanwhile, or not ours
    return found


def command_line(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")[:80]
    except OSError:
        return str(pid)


def last_line(log_path: Path) -> str:
    lines = [line.strip() for line in log_path.read_text(errors="replace").splitlines() if line.strip()]
    return lines[-1] if lines else "(no output)"


def slug(text: str) -> str:
    return "".join(c if c.isalnum() else "_" for c in text).strip("_")


# -- a campaign

def run_campaign(settings: TrialSettings, chosen: Sequence[Scenario],
                 progress: Callable[[str], None] = print) -> list[TrialResult]:
    settings.log_dir.mkdir(parents=True, exist_ok=True)
    inherit_sigint_unignored()
    plans = plan_trials(settings, chosen)
    results: list[TrialResult] = []
    try:
        for under_load in (False, True):
            phase = [p for p in plans if p.under_load == under_load]
            if not phase:
                continue
            hogs = cpu_hogs(os.cpu_count() or 1) if under_load else _no_hogs()
            with hogs, ThreadPoolExecutor(max_workers=settings.parallel) as pool:
                for result in pool.map(lambda p: run_trial(p, settings), phase):
                    results.append(result)
                    progress(describe(result, len(results), len(plans)))
    finally:
        kill_everything_started()
    return results


def inherit_sigint_unignored() -> None:
    """A shell starts background jobs with SIGINT ignored, and an ignored signal stays ignored across
    exec: a SIGINT that reached a target before its own handler would be lost, where under
    `ros2 launch` from a terminal it is not. Python's own handler is not inherited."""
    if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)


@contextmanager
def _no_hogs() -> Iterator[None]:
    yield


def describe(result: TrialResult, done: int, total: int) -> str:
    load = " under load" if result.plan.under_load else ""
    if result.outcome == "clean":
        outcome = f"ok, stopped in {result.stop_seconds:.1f} s"
    else:
        outcome = f"{result.outcome.upper()}: {result.failure} ({result.log_path})"
    return f"[{done:4d}/{total}] {result.plan.label}{load}: {outcome}"


OUTCOMES = ("clean", "finished first", "failed", "too early")
COLUMNS = ("trials", "SIGINT", "SIGTERM", "load", "twice", *OUTCOMES)


def counts(results: Sequence[TrialResult]) -> tuple[int, ...]:
    """The numbers of COLUMNS."""
    return (len(results), sum(r.plan.signal == signal.SIGINT for r in results),
            sum(r.plan.signal == signal.SIGTERM for r in results), sum(r.plan.under_load for r in results),
            sum(r.plan.again_after is not None for r in results),
            *(sum(r.outcome == outcome for r in results) for outcome in OUTCOMES))


def counts_table(results: Sequence[TrialResult], key: Callable[[TrialResult], str], title: str) -> list[str]:
    widths = [max(len(c), 6) for c in COLUMNS]
    header = f"{title:30s} " + " ".join(f"{c:>{w}s}" for c, w in zip(COLUMNS, widths, strict=True))
    rows = [header, "-" * len(header)]
    for name in dict.fromkeys(key(r) for r in results):
        numbers = counts([r for r in results if key(r) == name])
        rows.append(f"{name:30s} " + " ".join(f"{n:{w}d}" for n, w in zip(numbers, widths, strict=True)))
    return rows


def table(results: Sequence[TrialResult]) -> str:
    """Per scenario: trials, SIGINT/SIGTERM, under load, signalled twice, clean stops, failures,
    signals too early for any code of ours; then every trial that did not stop cleanly."""
    rows = counts_table(results, lambda r: r.plan.scenario.name, "scenario")
    stops = [r.stop_seconds for r in results if r.stop_seconds is not None]
    unclean = [r for r in results if r.outcome in ("failed", "too early")]
    failed = sum(r.outcome == "failed" for r in results)
    rows.append(f"{len(results)} trials, {failed} failed, {len(unclean) - failed} signalled too early; "
                f"slowest clean stop {max(stops, default=0.0):.1f} s after the signal")
    rows += [f"{r.outcome.upper()} {r.plan.label}{' under load' if r.plan.under_load else ''}: {r.failure} "
             f"({r.log_path})" for r in unclean]
    return "\n".join(rows)


def executable_table(results: Sequence[TrialResult]) -> str:
    """The same counts per executable: all its scenarios together."""
    return "\n".join(counts_table(results, lambda r: r.plan.scenario.executable, "executable"))


def write_results(results: Sequence[TrialResult], path: Path) -> None:
    """One JSON object per trial, for a report."""
    with open(path, "w") as out:
        for r in results:
            out.write(json.dumps({
                "scenario": r.plan.scenario.name, "executable": r.plan.scenario.executable,
                "trial": r.plan.number, "signal": r.plan.signal.name, "delay": round(r.plan.delay, 3),
                "under_load": r.plan.under_load, "again_after": r.plan.again_after, "outcome": r.outcome,
                "exit_code": r.exit_code,
                "stop_seconds": None if r.stop_seconds is None else round(r.stop_seconds, 3),
                "failure": r.failure, "log": str(r.log_path),
            }) + "\n")


# -- command line

def parse_args(argv: Sequence[str] | None) -> tuple[TrialSettings, argparse.Namespace]:
    """The settings, and the options that are not settings of trials (--list, --results)."""
    parser = argparse.ArgumentParser(prog="signal_trials", description=__doc__.split("\n\n")[0])
    parser.add_argument("--trials", type=int, default=10, help="trials per scenario (default 10)")
    parser.add_argument("--per-executable", action="store_true",
                        help="--trials per executable, shared out among its scenarios")
    parser.add_argument("--results", type=Path, default=None, help="write one JSON line per trial here")
    parser.add_argument("--max-delay", type=float, default=20.0, help="longest wait before the signal, s")
    parser.add_argument("--startup-share", type=float, default=0.3,
                        help="share of the trials signalled during the scenario's start-up (default 0.3)")
    parser.add_argument("--parallel", type=int, default=2, help="trials at once (default 2)")
    load = parser.add_mutually_exclusive_group()
    load.add_argument("--load", action="store_true", help="every trial with a busy loop on every core")
    load.add_argument("--load-share", type=float, default=0.0, help="share of the trials under load")
    parser.add_argument("--twice-share", type=float, default=0.0,
                        help="share of the trials whose signal comes twice, 0-0.5 s apart (Ctrl-C "
                             "pressed twice)")
    parser.add_argument("--only", default="", help="comma-separated scenario or executable names")
    parser.add_argument("--seed", type=int, default=int(time.time()), help="seed of the delays and signals")
    parser.add_argument("--exit-timeout", type=float, default=10.0, help="s a node may take to exit")
    parser.add_argument("--log-dir", type=Path, default=None, help="folder of the trials' logs")
    parser.add_argument("--list", action="store_true", help="list the scenarios and exit")
    args = parser.parse_args(argv)
    if args.trials < 1 or args.parallel < 1 or args.max_delay < 0 or not 0 <= args.load_share <= 1:
        parser.error("--trials and --parallel must be >= 1, --max-delay >= 0, --load-share within [0, 1]")
    settings = TrialSettings(
        trials=args.trials, per_executable=args.per_executable, max_delay=args.max_delay,
        startup_share=args.startup_share, parallel=args.parallel, twice_share=args.twice_share,
        load_share=1.0 if args.load else args.load_share, seed=args.seed, exit_timeout=args.exit_timeout,
        only=tuple(name.strip() for name in args.only.split(",") if name.strip()),
    )
    if args.log_dir is not None:
        settings = replace(settings, log_dir=args.log_dir)
    return settings, args


def main(argv: Sequence[str] | None = None) -> int:
    settings, options = parse_args(argv)
    try:
        chosen = selected(scenarios(), settings.only)
        if options.list:
            print("\n".join(f"{s.name}: {s.target.package} {s.executable}" for s in chosen))
            return 0
        print(f"seed {settings.seed}, logs in {settings.log_dir}", flush=True)
        results = run_campaign(settings, chosen, progress=lambda line: print(line, flush=True))
    except (RuntimeError, ValueError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    print(table(results))
    print(executable_table(results))
    if options.results is not None:
        write_results(results, options.results)
    return 1 if any(r.outcome == "failed" for r in results) else 0


if __name__ == "__main__":
    sys.exit(main())
