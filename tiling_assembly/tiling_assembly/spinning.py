"""Spinning a node until Ctrl-C, and stopping without noise: every node process's main loop.

rclpy Jazzy's `Executor.shutdown` does not wait for the callbacks still running on a
`MultiThreadedExecutor`'s worker threads (it tests its "shut down" flag right after setting it). A
callback still running when its node is destroyed fails ("cannot use Destroyable because destruction
was requested"), and the failure is printed as "The following exception was never retrieved" when
the task is collected: noise in every log at Ctrl-C. Waiting for the workers before destroying the
node avoids it. And a callback that races the context's shutdown at Ctrl-C can fail inside rclpy
(a take on a subscription whose context is gone): that is part of stopping, not a failure to report
with a traceback.
"""

from __future__ import annotations

import time
from concurrent.futures import ThreadPoolExecutor

from rclpy.executors import Executor, ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node


def spin_until_shutdown(node: Node, executor: Executor | None = None) -> None:
    """Spin `node` until Ctrl-C or shutdown, then stop the executor (see `stop_executor`).

    Errors raised once the context is shut down are part of stopping and are not raised; the caller
    destroys the node and shuts rclpy down afterwards.
    """
    spinner = executor if executor is not None else SingleThreadedExecutor(context=node.context)
    spinner.add_node(node)
    try:
        spinner.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception:
        if node.context.ok():
            raise
    finally:
        stop_executor(spinner)


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
