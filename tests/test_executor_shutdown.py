"""Stopping a node waits for the callbacks still running on its executor's threads."""

from __future__ import annotations

import gc
import signal
import subprocess
import sys
import threading
import time
import warnings
from pathlib import Path

import pytest
import rclpy
from conftest import stop_node_process
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.executors import MultiThreadedExecutor, SingleThreadedExecutor
from ros_helpers.isolated_domains import fresh_domain
from std_msgs.msg import Empty, String

from tiling_ros.spinning import GIL_FREE_GRACE, TEARDOWN_PATIENCE, Spinner

pytestmark = pytest.mark.ros


def test_a_running_callback_finishes_before_the_node_is_destroyed() -> None:
    context = fresh_domain().context
    node = rclpy.create_node("slow_callback", context=context)
    publisher = node.create_publisher(Empty, "slow_callback_done", 1)
    started, finished = threading.Event(), threading.Event()

    def slow() -> None:
        if started.is_set():
            return
        started.set()
        time.sleep(0.5)
        publisher.publish(Empty())  # fails if the node was destroyed meanwhile
        finished.set()

    node.create_timer(0.01, slow, callback_group=ReentrantCallbackGroup())
    spinner = Spinner(node, MultiThreadedExecutor(num_threads=2, context=context))
    spinner.start()
    try:
        assert started.wait(10.0)
        assert spinner.stop()
        assert finished.is_set()  # rclpy's own shutdown returns while the callback still sleeps
        assert spinner.failure is None
    finally:
        node.destroy_node()


def test_ctrl_c_lets_a_running_callback_publish_before_ros_shuts_down() -> None:
    """rclpy's own SIGINT handler would shut the context down under the callback ("publisher's
    context is invalid"); run_node waits for the callback first."""
    domain = fresh_domain()
    node = subprocess.Popen([sys.executable, str(Path(__file__).parent / "slow_callback_node.py")],
                            env=domain.environ(), stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    context = domain.context
    listener = rclpy.create_node("slow_callback_listener", context=context)
    heard: list[str] = []
    listener.create_subscription(String, "slow_callback", lambda m: heard.append(m.data), 10)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(listener)
    try:
        deadline = time.monotonic() + 20.0
        while "started" not in heard and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
        assert "started" in heard, "the node never ran its callback"
        started = len(heard)
        output = stop_node_process(node)  # the callback is now sleeping
        deadline = time.monotonic() + 3.0
        while "finished" not in heard[started:] and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
        assert node.returncode == 0, output
        assert "finished" in heard[started:], output
        for noise in ("never retrieved", "context is invalid"):  # tracebacks: stop_node_process
            assert noise not in output, output
    finally:
        if node.poll() is None:
            node.kill()
        executor.shutdown()
        listener.destroy_node()


@pytest.mark.parametrize("signal_name", ["SIGINT", "SIGTERM"])
def test_a_signal_that_breaks_the_import_of_a_node_module_exits_quietly(signal_name: str) -> None:
    """Ctrl-C while Open3D's C extension initialised came out as "ImportError: initialization
    failed" with two tracebacks and exit code 1."""
    result = _interrupted_startup(signal_name, "import")
    assert result.returncode == 0, result.stderr
    assert "Traceback" not in result.stderr and "ImportError" not in result.stderr


@pytest.mark.parametrize("signal_name", ["SIGINT", "SIGTERM"])
def test_a_signal_while_the_node_is_built_stops_it_once_built(signal_name: str) -> None:
    """A node interrupted half-built would leave what it started (a device thread, an inspection
    thread) running, unstopped, into the interpreter's exit."""
    result = _interrupted_startup(signal_name, "construction")
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == ["built", "stopped"], result.stdout + result.stderr
    assert "Traceback" not in result.stderr


@pytest.mark.parametrize("signal_name", ["SIGINT", "SIGTERM"])
def test_a_signal_while_the_executor_is_built_stops_the_node_without_noise(signal_name: str) -> None:
    """A signal landing in rclpy's Executor.__init__ left a half-built executor whose __del__
    printed "Exception ignored in ... Executor.__del__" with a traceback (once in a full test run)."""
    result = _interrupted_startup(signal_name, "executor")
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == ["built", "stopped"], result.stdout + result.stderr
    assert result.stderr == ""


def _interrupted_startup(signal_name: str, phase: str) -> subprocess.CompletedProcess[str]:
    script = Path(__file__).parent / "interrupted_startup_node.py"
    return subprocess.run([sys.executable, str(script), signal_name, phase], capture_output=True, text=True,
                          timeout=60)


def test_a_node_the_middleware_never_releases_still_ends_its_process() -> None:
    """A DDS participant's deletion blocked for good once over a lossy link (the process hung until
    killed); the process now leaves after TEARDOWN_PATIENCE with one line and exit code 0."""
    code, output, seconds = _ctrl_c("hanging_teardown_node.py", timeout=TEARDOWN_PATIENCE + 10.0)
    assert code == 0, output
    assert seconds >= TEARDOWN_PATIENCE
    assert output.strip().splitlines() == [
        f"hanging_teardown_node: the middleware did not release the node within {TEARDOWN_PATIENCE:g} s; "
        "exiting without it"]


def test_a_teardown_that_holds_the_interpreter_still_ends_the_process() -> None:
    """The Python deadline cannot run then: faulthandler's watchdog writes the stacks and the exit
    armed in the C library ends the process with the teardown's exit code, 0 (the node's work had
    stopped; exit code 1 made the experiment and `ros2 launch` report a crash, as CI once did)."""
    code, output, seconds = _ctrl_c("gil_holding_teardown_node.py", timeout=TEARDOWN_PATIENCE + 15.0)
    assert code == 0, output
    assert TEARDOWN_PATIENCE + GIL_FREE_GRACE <= seconds < TEARDOWN_PATIENCE + GIL_FREE_GRACE + 3.0
    assert "Timeout" in output and "destroy_node" in output


def test_a_teardown_that_crashes_still_ends_the_process_with_one_line() -> None:
    """Fast DDS crashed (SIGSEGV) inside rclpy's destroy_node after auction_node's work had stopped;
    the experiment and `ros2 launch` reported the node as killed. Now: one line, the stacks, exit 0."""
    code, output, seconds = _ctrl_c("crashing_teardown_node.py", timeout=TEARDOWN_PATIENCE + 10.0)
    assert code == 0, output
    assert seconds < TEARDOWN_PATIENCE, output
    lines = output.strip().splitlines()
    assert lines[0] == ("crashing_teardown_node: the middleware crashed while releasing the stopped node; "
                        "exiting without it (SIGSEGV)"), output
    assert "destroy_node" in output and "Traceback" not in output


def test_an_interpreter_exit_that_never_ends_does_not_keep_a_stopped_node_alive() -> None:
    code, output, _ = _ctrl_c("hanging_exit_node.py", timeout=10.0)
    assert code == 0, output
    assert output.split() == ["stopped"]


def test_a_stop_that_never_returns_still_ends_the_process_with_one_line() -> None:
    code, output, _ = _ctrl_c("hanging_stop_node.py", timeout=15.0)
    assert code == 1, output
    assert output.strip().splitlines() == [
        "hanging_stop_node: stopping took longer than 1 s (a bug); exiting without a clean stop"]


def _ctrl_c(script: str, timeout: float) -> tuple[int, str, float]:
    """Start a test node script, Ctrl-C it once it prints "ready": its exit code, its output after
    "ready" and the seconds it took to end."""
    node = subprocess.Popen([sys.executable, str(Path(__file__).parent / script)],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        assert node.stdout is not None and node.stdout.readline().strip() == "ready"
        stopped_at = time.monotonic()
        node.send_signal(signal.SIGINT)
        output, _ = node.communicate(timeout=timeout)
        return node.returncode, output, time.monotonic() - stopped_at
    finally:
        if node.poll() is None:
            node.kill()


def test_ctrl_c_anywhere_in_the_wait_leaves_the_spinner_stoppable() -> None:
    """A signal's KeyboardInterrupt can land at any instruction of `Spinner.wait`. Landing inside an
    `Event.wait`, it left the event's lock held (or raised RuntimeError: release unlocked lock), and
    `stop` then hung for good: create_base outlived launch's SIGKILL once. Here the interrupt is
    raised at each of the wait's instructions in turn, through a trace function."""
    context = fresh_domain().context
    for instruction in range(1, 200):
        outcome, counted = _interrupt_wait_at(context, instruction)
        assert outcome in ("KeyboardInterrupt", "returned"), f"instruction {instruction}: {outcome}"
        if counted < instruction:
            break  # the wait ended before reaching this instruction: every one was tried
    else:
        pytest.fail("the wait ran longer than expected")


def _interrupt_wait_at(context: rclpy.Context, instruction: int) -> tuple[str, int]:
    """Raise KeyboardInterrupt at the `instruction`-th traced step of `Spinner.wait` (the loop ends
    after 50 ms); then stop the spinner. (outcome, steps traced); a stop that hangs is an outcome."""
    node = rclpy.create_node(f"interrupted_wait_{instruction}", context=context)
    spinner = Spinner(node, SingleThreadedExecutor(context=context))
    spinner.start()
    steps = 0

    def trace(frame, event, arg):
        nonlocal steps
        frame.f_trace_opcodes = True
        steps += 1
        if steps == instruction:
            raise KeyboardInterrupt
        return trace

    threading.Timer(0.05, spinner._stopping.set).start()
    sys.settrace(trace)
    try:
        spinner.wait()
        outcome = "returned"
    except BaseException as error:
        outcome = type(error).__name__
    finally:
        sys.settrace(None)
    stopper = threading.Thread(target=spinner.stop, args=(1.0,), daemon=True)
    stopper.start()
    stopper.join(5.0)
    node.destroy_node()
    return ("stop hung" if stopper.is_alive() else outcome), steps


def test_a_task_the_loop_never_started_is_dropped_without_a_warning() -> None:
    """An action goal accepted just before the stop leaves a task the loop never runs; dropped as is,
    its coroutine printed "RuntimeWarning: coroutine ... was never awaited" at exit (base_navigator)."""
    context = fresh_domain().context
    node = rclpy.create_node("unstarted_task", context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    spinner = Spinner(node, executor)

    async def never_run() -> None:
        return None

    try:
        executor.create_task(never_run)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            assert spinner.stop(timeout=1.0)
            executor._tasks.clear()  # what the executor drops when it is gone
            gc.collect()
        assert [str(w.message) for w in caught if "never awaited" in str(w.message)] == []
    finally:
        node.destroy_node()
