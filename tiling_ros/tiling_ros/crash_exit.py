"""A process exit, with a line and every thread's stack, when the process crashes (SIGSEGV, SIGBUS)
inside a block: for the middleware's release of a node whose work has already stopped.

The handler is a Python function installed as the C signal handler (through ctypes), so it runs
on the crashing thread, whatever holds the interpreter there: it writes the line and the stacks
(faulthandler) straight to stderr's file descriptor and calls `_exit`. Should it never get the
interpreter (a crash on a middleware thread while another thread holds it), the caller's own
deadline still ends the process (`spinning.teardown_deadline`). Linux only; elsewhere the block
runs unguarded.
"""

from __future__ import annotations

import ctypes
import faulthandler
import os
import signal
import sys
from collections.abc import Iterator
from contextlib import contextmanager

_SignalHandler = ctypes.CFUNCTYPE(None, ctypes.c_int)
CRASH_SIGNALS = (signal.SIGSEGV, signal.SIGBUS)


def _c_library() -> ctypes.CDLL | None:
    if not sys.platform.startswith("linux"):
        return None
    library = ctypes.CDLL(None)
    library.signal.restype = ctypes.c_void_p
    library.signal.argtypes = (ctypes.c_int, ctypes.c_void_p)
    return library


@contextmanager
def on_crash(message: str, exit_code: int) -> Iterator[None]:
    """Run the block; a crash inside it writes `message` and the stacks on stderr and ends the
    process with `exit_code`. The previous handlers (faulthandler's, say) come back afterwards."""
    library = _c_library()
    if library is None:
        yield
        return

    def leave(signal_number: int) -> None:
        os.write(sys.stderr.fileno(), f"{message} ({signal.Signals(signal_number).name})\n".encode())
        faulthandler.dump_traceback(file=sys.stderr.fileno(), all_threads=True)
        os._exit(exit_code)

    handler = _SignalHandler(leave)
    pointer = ctypes.cast(handler, ctypes.c_void_p)
    previous = {number: library.signal(number, pointer) for number in CRASH_SIGNALS}
    try:
        yield
    finally:
        for number, earlier in previous.items():
            library.signal(number, earlier)
