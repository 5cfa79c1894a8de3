"""A node process's life: start ROS, build the node, spin until Ctrl-C, stop without noise.

Two things in rclpy Jazzy make a plain `rclpy.init` + `spin` noisy at Ctrl-C:
- rclpy's own SIGINT handler shuts the context down at once, while callbacks may still be running on
  executor threads; a publish or a take from one of them then fails ("publisher's context is
  invalid"), printed as "The following exception was never retrieved".
- `Executor.shutdown` does not wait for the callbacks still running (it tests its "shut down" flag
  right after setting it), so a node destroyed next fails them too ("cannot use Destroyable").

So rclpy's signal handlers are not installed: Ctrl-C and SIGTERM raise KeyboardInterrupt in the main
thread (`tiling_assembly.interrupts`, in place from the executable's first line), which only waits
while the executor spins in a thread of its own (`Spinner`). The spinning then ends, the running
callbacks are waited for, and only after that are the executor shut down, the node destroyed and
the context shut down; the last two get `TEARDOWN_PATIENCE` s (see `teardown_deadline`).
"""

from __future__ import annotations

import faulthandler
import inspect
import io
import os
import sys
import threading
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from typing import TypeVar

import rclpy
from rclpy.executors import Executor, ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from tiling_assembly.interrupts import (
    postponed_signals,
    raise_if_signalled,
    raise_keyboard_interrupt_on_signals,
    recorded_signals,
    skip_interpreter_exit,
)
from tiling_ros import crash_exit, exit_timer

NodeT = TypeVar("NodeT", bound=Node)

EXIT_BAD_INPUT = 2  # a parameter, structure file or other start-up input was rejected
TEARDOWN_PATIENCE = 3.0  # s the middleware gets to release a stopped node (launch escalates after 5 s)
STOP_PATIENCE = 10.0  # s for on_stop, the running callbacks (5 s) and on_shutdown together
GIL_FREE_GRACE = 1.0  # s after a deadline: the watchdogs that need no interpreter take over
NATIVE_EXIT_DELAY = 0.2  # s the faulthandler's stacks get to reach the log before the exit


def init_ros(args: list[str] | None = None) -> None:
    """`rclpy.init` without rclpy's signal handlers: SIGINT and SIGTERM raise KeyboardInterrupt."""
    raise_keyboard_interrupt_on_signals()  # again: a test or tool may call run_node directly
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)


def run_node(make_node: Callable[[], NodeT], startup_errors: tuple[type[Exception], ...] = (), *,
             args: list[str] | None = None, executor: Callable[[], Executor] = SingleThreadedExecutor,
             on_stop: Callable[[NodeT], None] | None = None, on_shutdown: Callable[[NodeT], None] | None = None,
             error_prefix: str = "error", stop_patience: float = STOP_PATIENCE) -> int:
    """Run one node for a whole process; returns the exit code.

    A start-up error of the types given prints one line `<error_prefix>: <error>` on stderr and gives
    `EXIT_BAD_INPUT`. Ctrl-C or SIGTERM stops the node (exit code 0), also during start-up: a signal
    while `make_node` runs takes effect once the node is built, so that a node with threads or
    devices already started is stopped like any other. Stopping: `on_stop` asks long callbacks to
    return (a navigation, a mission), the callbacks still running are waited for, `on_shutdown`
    runs, the node is destroyed; each of the two stages has a deadline (`stop_deadline`,
    `teardown_deadline`). A further signal while it stops is ignored (it could only cut the stop
    short and leave threads inside rclpy at exit, which aborts the process).
    """
    node: NodeT | None = None
    spinner: Spinner | None = None
    try:
        init_ros(args)
        raise_if_signalled()  # also here: rclpy.init imports the middleware's type support
        try:
            with postponed_signals():  # also the executor: one cut short fails in its __del__
                node = make_node()
                spinner = Spinner(node, executor())
                spinner.start()
        except Exception as error:  # a signal meanwhile came out as KeyboardInterrupt instead
            if not isinstance(error, startup_errors):
                raise
            print(f"{error_prefix}: {error}", file=sys.stderr)
            return EXIT_BAD_INPUT
        spinner.wait()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        with recorded_signals():
            if node is not None:
                with stop_deadline(node.get_name(), stop_patience):
                    stop_node(node, spinner, on_stop, on_shutdown)
            with teardown_deadline(node.get_name() if node is not None else error_prefix):
                if node is not None:
                    node.destroy_node()
                rclpy.try_shutdown()
            skip_interpreter_exit()
    if spinner is not None and spinner.failure is not None:
        raise spinner.failure  # a callback's error: a bug, with its traceback
    return 0


def stop_node(node: NodeT, spinner: Spinner | None, on_stop: Callable[[NodeT], None] | None,
              on_shutdown: Callable[[NodeT], None] | None) -> None:
    """Stop a node's work and its executor (the caller destroys the node, see `teardown_deadline`)."""
    if on_stop is not None:
        call_reporting_errors(on_stop, node, "while stopping")
    if spinner is not None and not spinner.stop():
        print(f"{node.get_name()}: a callback was still running 5 s after the stop; exiting anyway",
              file=sys.stderr)
    if on_shutdown is not None:
        call_reporting_errors(on_shutdown, node, "while shutting down")


@contextmanager
def teardown_deadline(name: str, patience: float = TEARDOWN_PATIENCE) -> Iterator[None]:
    """Leave the process with exit code 0 when the middleware has not released the node within
    `patience` s, or crashes releasing it: the node's work has stopped, only DDS's own teardown is
    left. A DDS participant's deletion now and then blocks for good (seen once in 8 trials over a
    lossy link); without this, the process would hang until killed. It also crashed (SIGSEGV in
    rclpy's `destroy_node`, auction_node, twice in about 20 runs of one end-to-end test), which
    `ros2 launch` and the experiment report as the node dying, though nothing of its work was lost."""
    with exit_unless_done_within(
            patience, f"{name}: the middleware did not release the node within {patience:g} s; exiting without it",
            exit_code=0), crash_exit.on_crash(
            f"{name}: the middleware crashed while releasing the stopped node; exiting without it", exit_code=0):
        yield


@contextmanager
def stop_deadline(name: str, patience: float = STOP_PATIENCE) -> Iterator[None]:
    """Leave the process with one line and exit code 1 when stopping the node's own work takes
    longer than `patience` s: every step of the stop has a timeout of its own, so this is a bug, but
    the process must still end before launch's SIGKILL (15 s after its SIGINT)."""
    with exit_unless_done_within(
            patience, f"{name}: stopping took longer than {patience:g} s (a bug); exiting without a clean stop",
            exit_code=1):
        yield


@contextmanager
def exit_unless_done_within(patience: float, message: str, exit_code: int) -> Iterator[None]:
    """The block, or `message` on stderr and `os._exit(exit_code)` once it has run `patience` s.

    That takes the interpreter: a hang inside a C call that holds it (rclpy's publisher destroy
    blocked so in vi_node, sim_world and planner_node) would keep this thread from running. So
    `GIL_FREE_GRACE` s later Python's faulthandler, whose watchdog needs no interpreter, writes every
    thread's stack on stderr, to find the hang, and an exit armed in the C library (`exit_timer`)
    ends the process with the same `exit_code`; where that cannot be armed, faulthandler exits (1)."""
    done = threading.Event()

    def give_up_waiting() -> None:
        if not done.wait(patience):
            print(message, file=sys.stderr, flush=True)
            sys.stdout.flush()
            os._exit(exit_code)

    threading.Thread(target=give_up_waiting, name="deadline", daemon=True).start()
    native_exit = exit_timer.arm(patience + GIL_FREE_GRACE + NATIVE_EXIT_DELAY, exit_code)
    try:
        faulthandler.dump_traceback_later(patience + GIL_FREE_GRACE, exit=native_exit is None)
    except (io.UnsupportedOperation, ValueError, RuntimeError):
        pass  # stderr is no file (a test captures it): the stacks cannot be written, the exits still stand
    try:
        yield
    finally:
        faulthandler.cancel_dump_traceback_later()
        if native_exit is not None:
            native_exit.disarm()
        done.set()


def call_reporting_errors(hook: Callable[[NodeT], None], node: NodeT, when: str) -> None:
    """A stop hook's error is one line: the stop goes on."""
    try:
        hook(node)
    except Exception as error:
        print(f"{node.get_name()}: {when}: {error}", file=sys.stderr)


class Spinner:
    """An executor spun by a loop of our own on a background thread, so that stopping can first end
    the loop, then wait for the callbacks still running, and only then shut the executor down.

    rclpy's `Executor.shutdown` called while another thread spins destroys the executor's guard
    condition under a callback that is about to trigger it ("cannot use Destroyable"), and does not
    wait for running callbacks. Two private parts of rclpy Jazzy are used to wait, each only if
    present: the executor's count of running callbacks and a `MultiThreadedExecutor`'s thread pool
    (whose thread list alone is not enough: a worker can start its callback before it is listed).
    """

    POLL = 0.1  # s; how long one spin_once may wait, hence how quickly a stop is noticed

    def __init__(self, node: Node, executor: Executor | None = None) -> None:
        self.node = node
        self.executor = executor if executor is not None else SingleThreadedExecutor(context=node.context)
        self.executor.add_node(node)
        self.failure: Exception | None = None
        self._stopping = threading.Event()
        # Waited on instead of the thread: in Python 3.11 a Thread.join interrupted by Ctrl-C marks
        # the thread stopped while it still runs, and a thread still in rclpy at exit aborts the process.
        self._loop_ended = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        self._thread = threading.Thread(target=self._loop, name=f"{self.node.get_name()}_executor", daemon=True)
        self._thread.start()

    def _loop_may_run(self) -> bool:
        """Whether the loop runs or ran. A thread that is not alive yet has not entered the loop, and
        once `_stopping` is set it never will."""
        return self._thread is not None and (self._thread.is_alive() or self._loop_ended.is_set())

    def _loop(self) -> None:
        try:
            while not self._stopping.is_set() and self.node.context.ok():
                self.executor.spin_once(timeout_sec=self.POLL)
        except ExternalShutdownException:
            pass
        except Exception as error:
            if self.node.context.ok():
                self.failure = error
        finally:
            self._loop_ended.set()

    def wait(self) -> None:
        """Until the loop ends (the context shut down, or a callback failed); Ctrl-C interrupts it.

        Polls with a plain sleep: the KeyboardInterrupt of a signal can land between a lock's
        acquisition and the block that releases it, and an `Event.wait` interrupted there leaves the
        event's lock held for good; `stop`, waiting on the same event, then hung the process past
        launch's SIGKILL (create_base, once in a full test run)."""
        while not self._loop_ended.is_set():
            time.sleep(self.POLL)

    def stop(self, timeout: float = 5.0) -> bool:
        """End the loop, wait up to `timeout` s for running callbacks, shut the executor down.
        False if some callback was still running at the deadline."""
        deadline = time.monotonic() + timeout
        self._stopping.set()
        finished = self._loop_ended.wait(timeout) if self._loop_may_run() else True
        running = getattr(self.executor, "_work_tracker", None)

        def wait_for_running_callbacks() -> bool:
            if running is None or not hasattr(running, "wait"):
                return True
            return bool(running.wait(max(0.0, deadline - time.monotonic())))

        finished = wait_for_running_callbacks() and finished
        pool = getattr(self.executor, "_executor", None)
        if isinstance(pool, ThreadPoolExecutor):
            # the callbacks already handed to the pool still run: cancelled, their rclpy handler
            # coroutines are never awaited ("RuntimeWarning: coroutine ... was never awaited" at exit)
            pool.shutdown(wait=False)
            for worker in list(getattr(pool, "_threads", ())):
                worker.join(max(0.0, deadline - time.monotonic()))
            finished = wait_for_running_callbacks() and finished  # one taken just before the cancel
        self._discard_unstarted_tasks()
        self.executor.shutdown(timeout_sec=0)
        return finished

    def _discard_unstarted_tasks(self) -> None:
        """Close the coroutines of tasks the loop never started (an action goal accepted just before
        the stop): dropped unstarted, each printed "RuntimeWarning: coroutine ... was never awaited"."""
        tasks = getattr(self.executor, "_tasks", ())
        for task, *_ in list(tasks):
            coroutine = getattr(task, "_handler", None)
            if inspect.iscoroutine(coroutine) and inspect.getcoroutinestate(coroutine) == inspect.CORO_CREATED:
                coroutine.close()
