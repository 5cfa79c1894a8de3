"""A process exit armed in the C library, which fires even while some thread holds the interpreter.

A DDS entity's deletion now and then blocks for good inside a C call that holds Python's
interpreter lock (Fast DDS deleting a publisher, seen in sim_world, vi_node, planner_node): no
Python thread runs again, so a Python deadline cannot end the process. Python's faulthandler can
(its watchdog needs no interpreter), but only with exit code 1, which `ros2 launch` and the
experiment report as a crash, though the node's work had stopped cleanly.

So the exit is armed as a POSIX timer that, when it expires, starts a thread of the C library's
own calling `_exit(code)` (`timer_create` with SIGEV_THREAD; the timer's value is the argument).
Linux with glibc only; elsewhere `arm` returns None and the caller keeps its Python deadline.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import sys

_CLOCK_MONOTONIC = 1
_SIGEV_THREAD = 2


class _SigEvent(ctypes.Structure):
    """glibc's `struct sigevent` (64 bytes) for SIGEV_THREAD: the value is passed to the function."""

    _fields_ = (
        ("value", ctypes.c_void_p),  # union sigval; as an int it is the exit code
        ("signo", ctypes.c_int),
        ("notify", ctypes.c_int),
        ("function", ctypes.c_void_p),
        ("attributes", ctypes.c_void_p),
        ("padding", ctypes.c_byte * 32),
    )


class _TimeSpec(ctypes.Structure):
    _fields_ = (("seconds", ctypes.c_long), ("nanoseconds", ctypes.c_long))


class _TimerSpec(ctypes.Structure):
    _fields_ = (("interval", _TimeSpec), ("value", _TimeSpec))


class ExitTimer:
    """An armed `_exit(code)`; `disarm` before it expires to keep the process."""

    def __init__(self, library: ctypes.CDLL, timer: ctypes.c_void_p) -> None:
        self._library = library
        self._timer = timer

    def disarm(self) -> None:
        if self._timer is not None:
            self._library.timer_delete(self._timer)
            self._timer = None


def _c_library() -> ctypes.CDLL | None:
    if not sys.platform.startswith("linux"):
        return None
    for name in (None, ctypes.util.find_library("rt")):  # timer_create moved into libc in glibc 2.34
        library = ctypes.CDLL(name, use_errno=True)
        if hasattr(library, "timer_create") and hasattr(library, "_exit"):
            return library
    return None


def arm(seconds: float, code: int) -> ExitTimer | None:
    """End the process with `code` in `seconds` s, whatever its threads are doing; None if this
    platform cannot (the caller then relies on its own deadline)."""
    library = _c_library()
    if library is None:
        return None
    event = _SigEvent(value=code, notify=_SIGEV_THREAD,
                      function=ctypes.cast(library._exit, ctypes.c_void_p).value)
    timer = ctypes.c_void_p()
    if library.timer_create(_CLOCK_MONOTONIC, ctypes.byref(event), ctypes.byref(timer)) != 0:
        return None
    whole = int(seconds)
    expiry = _TimerSpec(value=_TimeSpec(whole, int((seconds - whole) * 1e9)))
    if library.timer_settime(timer, 0, ctypes.byref(expiry), None) != 0:
        library.timer_delete(timer)
        return None
    return ExitTimer(library, timer)
