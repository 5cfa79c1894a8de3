"""The command line of tools/independent_scenes.py and tools/score_inspection.py: a bad argument or
input is one line `error: ...` on stderr and exit code 2, Ctrl-C exit code 130.

Not run by itself; the two tools import it from their own folder.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence

EXIT_BAD_INPUT = 2
EXIT_INTERRUPTED = 130  # as a shell reports a process ended by SIGINT


class InputError(Exception):
    """Bad arguments or a bad input file: one line for the user."""


class OneLineParser(argparse.ArgumentParser):
    """An argument parser whose errors are one line, without argparse's usage block."""

    def error(self, message: str) -> None:  # type: ignore[override]
        print(f"error: {message}", file=sys.stderr)
        raise SystemExit(EXIT_BAD_INPUT)


def run_command(parser: argparse.ArgumentParser, run: Callable[[argparse.Namespace], int],
                argv: Sequence[str] | None = None) -> int:
    """`run` on the parsed `argv`; its exit code, or the exit code of an InputError or Ctrl-C."""
    args = parser.parse_args(argv)
    try:
        return run(args)
    except InputError as error:
        print(f"error: {error}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        return EXIT_INTERRUPTED
