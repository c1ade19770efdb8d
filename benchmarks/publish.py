"""Publish measured figures: copy the results of ``build/benchmarks/results/`` that were
measured at a commit into the committed ``benchmarks/results/`` and render
``docs/benchmarks.md`` from them.

Runs write outside the tracked tree so that no run changes the checkout the next one
measures; this is the one step that writes the tracked results. It refuses a checkout with
uncommitted changes (the page would not match any commit) and skips every result measured
at uncommitted changes (nobody can check out what it measured).

    python benchmarks/publish.py [--results DIR]     (``make bench-publish``)
"""

from __future__ import annotations

import argparse
import shutil
import sys
from pathlib import Path

import report
from results import (
    DIRTY,
    PUBLISHED,
    RESULTS,
    ResultsError,
    commit,
    measured_clean,
    read_results,
)


def publish(measured: Path, published: Path) -> list[Path]:
    """Copy each result measured at a commit; say which were skipped and why."""
    copied = []
    for path in sorted(measured.glob("*.json")):
        record = read_results(path)
        if not measured_clean(record):
            print(f"bench-publish: skipped {path.name}, measured at uncommitted changes "
                  f"({record['commit']}); rerun it at a clean commit.")
            continue
        published.mkdir(parents=True, exist_ok=True)
        copied.append(Path(shutil.copy2(path, published / path.name)))
    return copied


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--results", type=Path, default=RESULTS,
                        help="folder the runs wrote (default: build/benchmarks/results)")
    args = parser.parse_args(argv)
    if commit().endswith(DIRTY):
        print("bench-publish: the checkout has uncommitted changes; commit them first, so "
              "that the published figures and page belong to a commit.", file=sys.stderr)
        return 2
    if not args.results.is_dir():
        print(f"bench-publish: no results folder {args.results}; run `make bench` (or one "
              "benchmark) first.", file=sys.stderr)
        return 2
    try:
        copied = publish(args.results, PUBLISHED)
    except ResultsError as exc:
        print(f"bench-publish: {exc}", file=sys.stderr)
        return 2
    print(f"bench-publish: {len(copied)} result(s) -> {PUBLISHED}")
    return report.main([])


if __name__ == "__main__":
    sys.exit(main())
