"""``tactile-sensor bag recover BAG [--out DIR]``: a whole bag from a killed recorder's.

Exit codes: 0 recovered, 1 nothing to recover or cannot write (one sentence on stderr),
2 bad command line.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from .errors import RecordingError


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="tactile-sensor bag",
        description="Work on rosbag2 bags the recorder wrote.")
    verbs = p.add_subparsers(dest="verb", required=True)
    recover = verbs.add_parser(
        "recover", help="write a whole bag (index, metadata.yaml) from a damaged one",
        description="Read every whole chunk of a bag whose recorder was killed or ran out "
                    "of disk (cut MCAP files, no metadata.yaml, an interrupted sqlite3 "
                    "transaction) and write them as a new, valid rosbag2 bag.")
    recover.add_argument("bag", type=Path, help="rosbag2 folder, or one .mcap/.db3 file")
    recover.add_argument("--out", type=Path, default=None,
                         help="new bag folder (default: BAG-recovered beside BAG)")
    return p


def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(sys.argv[1:] if argv is None else argv)
    from .recovery import recover  # after parsing: --help stays fast

    try:
        result = recover(args.bag, args.out)
    except RecordingError as err:
        print(f"tactile-sensor bag recover: {err}", file=sys.stderr)
        return 1
    print(f"{result.summary()}; wrote {result.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
