"""The side-by-side benchmarks refuse a revision that is not a commit in one sentence,
before they start anything."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

BENCHMARKS = Path(__file__).resolve().parents[2] / "benchmarks"
pytestmark = pytest.mark.slow  # each case starts the benchmark's process


@pytest.mark.parametrize("bench", ["bench_driver.py", "bench_array_driver.py",
                                   "bench_stack.py"])
def test_an_unknown_revision_is_one_sentence(bench):
    done = subprocess.run([sys.executable, str(BENCHMARKS / bench), "--compare",
                           "no-such-revision", "--seconds", "1"],
                          capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 2
    assert done.stderr.strip().splitlines() == [
        f"{bench[:-3]}: --compare 'no-such-revision' is not a commit of this repository; "
        "give a hash, branch or tag that 'git log --oneline' shows."]
