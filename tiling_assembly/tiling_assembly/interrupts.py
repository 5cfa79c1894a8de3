"""Ctrl-C and SIGTERM as KeyboardInterrupt, from an executable's first line of its own to its last.

`ros2 launch` stops a node by sending SIGINT, later SIGTERM, to its process alone, at any moment:
also while Python still imports rclpy, the messages or Open3D, which takes about a second and much
longer on a loaded machine. Python's own handling then prints a traceback (SIGINT) or dies by the
signal (SIGTERM, exit code -15). So the installed executables do not import their node module
directly: `run_executable` first makes both signals raise KeyboardInterrupt, then imports the
module and runs its `main`, which stops the node itself (`tiling_ros.spinning.run_node`).

This module imports nothing but the standard library, so that the handlers are in place a few
milliseconds after the interpreter starts. What comes before (the interpreter's own start and
the script setuptools generates, ~50 ms) cannot be covered from Python.
"""

from __future__ import annotations

import importlib
import os
import signal
import sys
import threading
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from types import FrameType
from typing import Any

signalled = threading.Event()  # Ctrl-C or SIGTERM arrived


def _interrupt(signum: int, frame: FrameType | None) -> None:
    if signalled.is_set():
        return  # stopping already: Ctrl-C pressed twice, or launch's SIGTERM after its SIGINT
    signalled.set()
    # the KeyboardInterrupt may land between a coroutine's creation and its await (rclpy's
    # executor: "coroutine 'await_or_execute' was never awaited" when it is collected): expected
    # of a stop, like the unraisable KeyboardInterrupt below
    warnings.filterwarnings("ignore", message="coroutine .* was never awaited", category=RuntimeWarning)
    raise KeyboardInterrupt


def _drop_signalled_unraisable(unraisable: Any) -> None:
    """A KeyboardInterrupt raised where Python cannot pass it on (an import lock's clean-up
    callback, a finaliser) is printed as "Exception ignored in ..." with a traceback; the signal is
    recorded in `signalled` and acted on by `raise_if_signalled`, so it is dropped quietly."""
    if isinstance(unraisable.exc_value, KeyboardInterrupt) and signalled.is_set():
        return
    _report_unraisable(unraisable)


_report_unraisable = sys.unraisablehook


def raise_keyboard_interrupt_on_signals() -> None:
    """SIGINT and SIGTERM raise KeyboardInterrupt in the main thread (also SIGINT when the parent
    left it ignored, as a shell does for background jobs)."""
    sys.unraisablehook = _drop_signalled_unraisable
    signal.signal(signal.SIGINT, _interrupt)
    signal.signal(signal.SIGTERM, _interrupt)


def raise_if_signalled() -> None:
    """KeyboardInterrupt if a signal came: after imports, in case a library swallowed it. Libraries
    that fall back when an optional module fails to import can swallow the KeyboardInterrupt that
    broke that import (seen under load: xml.etree's C accelerator imported by networkx, numpy's
    lazy submodules under scipy's array_api_compat); the node then ran on as if never signalled."""
    if signalled.is_set():
        raise KeyboardInterrupt


@contextmanager
def recorded_signals() -> Iterator[list[int]]:
    """Within the block, SIGINT and SIGTERM are only recorded, in the list it yields; the handlers
    are restored at its end. Only the main thread receives Python's signals, so in another thread
    this changes nothing; neither does it for a handler not set from Python."""
    arrived: list[int] = []
    if threading.current_thread() is not threading.main_thread():
        yield arrived
        return
    previous: dict[int, Any] = {}
    try:
        for signum in (signal.SIGINT, signal.SIGTERM):
            if signal.getsignal(signum) is not None:
                previous[signum] = signal.signal(signum, lambda s, frame: arrived.append(s))
        yield arrived
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)


@contextmanager
def postponed_signals() -> Iterator[None]:
    """SIGINT and SIGTERM arriving within the block take effect at its end, as if sent then.

    For work that a KeyboardInterrupt must not cut in two. Open3D's import, interrupted, leaves
    tensors allocated that Open3D's own check at program end counts as leaks: it then calls
    `exit(1)` after Python has exited 0.
    """
    arrived: list[int] = []
    try:
        with recorded_signals() as arrived:
            yield
    finally:
        if arrived:
            signal.raise_signal(arrived[0])  # now handled as it would have been


_skip_interpreter_exit = False


def skip_interpreter_exit() -> None:
    """Ask `run_executable` to end the process at once when `main` returns, without the
    interpreter's own clean-up: called once a node has been stopped and torn down, because freeing
    what is left of the middleware at exit now and then blocks for good (an assembly node hung
    "Garbage-collecting" at exit until the experiment killed it)."""
    global _skip_interpreter_exit
    _skip_interpreter_exit = True


def _leave(code: int) -> int:
    if _skip_interpreter_exit:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    return code


def run_executable(module_name: str, interrupted_exit_code: int = 0) -> int:
    """`module_name.main()` as the whole life of a process; its exit code.

    A signal during the module's import ends the process with `interrupted_exit_code` and nothing
    on the terminal: nothing has started yet that would need stopping. Once `main` runs, stopping is
    its own job; a KeyboardInterrupt it lets out still ends the process quietly. A node's `main`
    asks for the process to end without the interpreter's clean-up (`skip_interpreter_exit`).
    """
    raise_keyboard_interrupt_on_signals()
    try:
        main = importlib.import_module(module_name).main
        raise_if_signalled()
        return _leave(int(main() or 0))
    except KeyboardInterrupt:
        return _leave(interrupted_exit_code)
    except Exception:
        if signalled.is_set():
            # the signal broke an import on its way out: a C extension's initialisation (Open3D's)
            # turns the KeyboardInterrupt into "ImportError: initialization failed"
            return interrupted_exit_code
        raise
    finally:
        # On its way out. The interpreter's exit takes a moment (the middleware tears down), and it
        # gives Python's handlers back to the default action: a signal then would kill the process
        # (exit -2 or -15 after a clean stop). Ignored signals stay ignored.
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_IGN)


def run_command(module_name: str) -> int:
    """`run_executable` for a command-line tool (plan, classify, replay_bag, ...): an interruption,
    also one while it still imports, exits 130 as shells report Ctrl-C; what the tool finished
    before stays written (each tool writes its results as it goes or not at all)."""
    return run_executable(module_name, interrupted_exit_code=130)
