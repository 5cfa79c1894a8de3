"""A node module whose import a signal breaks the way it breaks a C extension's initialisation:
the KeyboardInterrupt comes out as "ImportError: initialization failed" (tests/interrupted_startup_node.py)."""

from __future__ import annotations

import time

from interrupted_startup_node import signal_myself

try:
    signal_myself()
    time.sleep(5.0)
except KeyboardInterrupt as interrupt:
    raise ImportError("initialization failed") from interrupt


def main() -> int:
    raise AssertionError("the import was to fail")
