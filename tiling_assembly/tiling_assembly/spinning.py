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

import threading
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
    """Stop `executor` and wait up to `timeout` s for the callbacks still running on its threads."""
    executor.shutdown(timeout_sec=timeout)
    pool = getattr(executor, "_executor", None)  # a MultiThreadedExecutor's workers (not public API)
    if not isinstance(pool, ThreadPoolExecutor):
        return
    workers: list[threading.Thread] = list(getattr(pool, "_threads", ()))
    pool.shutdown(wait=False, cancel_futures=True)
    deadline = time.monotonic() + timeout
    for worker in workers:
        worker.join(max(0.0, deadline - time.monotonic()))
