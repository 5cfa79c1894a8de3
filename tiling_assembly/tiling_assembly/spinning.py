"""A node process's life: start ROS, build the node, spin until Ctrl-C, stop without noise.

Two things in rclpy Jazzy make a plain `rclpy.init` + `spin` noisy at Ctrl-C:
- rclpy's own SIGINT handler shuts the context down at once, while callbacks may still be running on
  executor threads; a publish or a take from one of them then fails ("publisher's context is
  invalid"), printed as "The following exception was never retrieved".
- `Executor.shutdown` does not wait for the callbacks still running (it tests its "shut down" flag
  right after setting it), so a node destroyed next fails them too ("cannot use Destroyable").

So rclpy's signal handlers are not installed: Ctrl-C and SIGTERM raise KeyboardInterrupt in the main
thread, which only waits while the executor spins in a thread of its own. The executor is then
stopped and its running callbacks are waited for, and only after that are the node destroyed and the
context shut down.
"""

from __future__ import annotations

import signal
import sys
import threading
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from types import FrameType
from typing import TypeVar

import rclpy
from rclpy.executors import Executor, ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

NodeT = TypeVar("NodeT", bound=Node)

EXIT_BAD_INPUT = 2  # a parameter, structure file or other start-up input was rejected


def _interrupt(signum: int, frame: FrameType | None) -> None:
    raise KeyboardInterrupt


def init_ros(args: list[str] | None = None) -> None:
    """`rclpy.init` without rclpy's signal handlers: SIGINT and SIGTERM raise KeyboardInterrupt."""
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    signal.signal(signal.SIGINT, _interrupt)  # also when the parent shell left SIGINT ignored
    signal.signal(signal.SIGTERM, _interrupt)


def run_node(make_node: Callable[[], NodeT], startup_errors: tuple[type[Exception], ...] = (), *,
             args: list[str] | None = None, executor: Callable[[], Executor] = SingleThreadedExecutor,
             on_shutdown: Callable[[NodeT], None] | None = None, error_prefix: str = "error") -> int:
    """Run one node for a whole process; returns the exit code.

    A start-up error of the types given prints one line `<error_prefix>: <error>` on stderr and gives
    `EXIT_BAD_INPUT`. Ctrl-C or SIGTERM stops the node (exit code 0), also during start-up. The node's
    `on_shutdown` runs after its callbacks have finished and before it is destroyed.
    """
    init_ros(args)
    try:
        try:
            node = make_node()
        except startup_errors as error:
            print(f"{error_prefix}: {error}", file=sys.stderr)
            return EXIT_BAD_INPUT
        try:
            spin_until_shutdown(node, executor())
        finally:
            if on_shutdown is not None:
                try:
                    on_shutdown(node)
                except Exception as error:
                    print(f"{node.get_name()}: while shutting down: {error}", file=sys.stderr)
            node.destroy_node()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        rclpy.try_shutdown()
    return 0


def spin_until_shutdown(node: Node, executor: Executor | None = None) -> None:
    """Spin `node` on a thread of its own until Ctrl-C or shutdown, then stop the executor and wait
    for its running callbacks (see `stop_executor`).

    An error raised by a callback stops the spinning and is raised here, unless the context had
    already shut down (then it is part of stopping). The caller destroys the node afterwards.
    """
    spinner = executor if executor is not None else SingleThreadedExecutor(context=node.context)
    spinner.add_node(node)
    failures: list[Exception] = []

    def spin() -> None:
        try:
            spinner.spin()
        except ExternalShutdownException:
            pass
        except Exception as error:
            if node.context.ok():
                failures.append(error)

    thread = threading.Thread(target=spin, name=f"{node.get_name()}_executor", daemon=True)
    thread.start()
    try:
        while thread.is_alive():
            thread.join(0.5)
    except KeyboardInterrupt:
        pass
    finally:
        stop_executor(spinner)
        thread.join(5.0)
    if failures:
        raise failures[0]


def stop_executor(executor: Executor, timeout: float = 5.0) -> None:
    """Stop `executor` and wait up to `timeout` s for the callbacks still running on its threads.

    Two private parts of rclpy Jazzy are used, each only if present: the executor's count of running
    callbacks (what `shutdown` means to wait on), and a `MultiThreadedExecutor`'s thread pool. The
    pool's thread list alone is not enough: a worker can start its callback before the thread that
    created it has added it to the list.
    """
    deadline = time.monotonic() + timeout
    executor.shutdown(timeout_sec=timeout)
    running = getattr(executor, "_work_tracker", None)

    def wait_for_running_callbacks() -> None:
        if running is not None and hasattr(running, "wait"):
            running.wait(max(0.0, deadline - time.monotonic()))

    wait_for_running_callbacks()
    pool = getattr(executor, "_executor", None)
    if isinstance(pool, ThreadPoolExecutor):
        pool.shutdown(wait=False, cancel_futures=True)
        for worker in list(getattr(pool, "_threads", ())):
            worker.join(max(0.0, deadline - time.monotonic()))
    wait_for_running_callbacks()  # a callback taken from the queue just before it was cancelled
