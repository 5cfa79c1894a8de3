"""A signal that lands where Python cannot raise (a finaliser, an import lock's clean-up) is still
acted on, and prints nothing (seen: 'Exception ignored in: <function _get_module_lock...>')."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

PROGRAM = textwrap.dedent("""
    import os, signal, sys, threading, time
    sys.path.insert(0, sys.argv[1])
    from tiling_assembly import interrupts
    interrupts.raise_keyboard_interrupt_on_signals()

    class SlowFinaliser:
        def __del__(self):
            time.sleep(1.0)  # the signal arrives in here

    threading.Timer(0.3, lambda: os.kill(os.getpid(), signal.SIGINT)).start()
    finalised = SlowFinaliser()
    del finalised
    try:
        interrupts.raise_if_signalled()
    except KeyboardInterrupt:
        print("stopped")
""")


def test_a_signal_in_a_finaliser_is_acted_on_quietly() -> None:
    result = subprocess.run([sys.executable, "-c", PROGRAM, str(REPO / "tiling_assembly")],
                            capture_output=True, text=True, timeout=30)
    assert result.returncode == 0 and result.stdout.strip() == "stopped"
    assert result.stderr == "", result.stderr
