"""`validate`: load structure files, report every rule they break, print a summary.

    ros2 run tiling_assembly validate FILE [FILE ...] [--quiet]

Exit code 0 when every file is valid, 2 when one is not (one line per invalid file on stderr).
"""

from __future__ import annotations

import argparse
import sys

from tiling_assembly.structure import StructureError
from tiling_assembly.structure_file import load_structure
from tiling_assembly.summary import summarize


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="validate", description="Validate structure files and print their summary."
    )
    parser.add_argument("files", nargs="+", metavar="FILE", help="structure YAML file")
    parser.add_argument("--quiet", action="store_true", help="print only errors")
    args = parser.parse_args(argv)
    status = 0
    for path in args.files:
        try:
            structure = load_structure(path)
        except StructureError as error:
            print(f"error: {error}", file=sys.stderr)
            status = 2
            continue
        if not args.quiet:
            print(summarize(structure))
            print()
    return status


if __name__ == "__main__":
    sys.exit(main())
