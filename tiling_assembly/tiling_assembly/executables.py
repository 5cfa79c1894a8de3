"""The command this package installs (setup.py). It catches Ctrl-C and SIGTERM before its module
loads (`tiling_assembly.interrupts`)."""

from tiling_assembly.interrupts import run_command


def validate() -> int:
    return run_command("tiling_assembly.validate")
