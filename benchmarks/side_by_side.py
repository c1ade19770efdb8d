"""Another commit's nodes beside this checkout's, in one benchmark run.

CPU and latency figures do not carry from one machine to another, nor from one hour of a
shared machine to the next, but a ratio measured in one run does. ``variants(REV)`` unpacks
the ``tactile_sensor`` Python sources of commit REV (``git archive``, into a temporary
folder that is removed afterwards), so a benchmark starts that revision's node with
PYTHONPATH pointing at them, against this checkout's built interfaces and mock hardware.
``interleaved`` alternates the order of the variants from round to round (A B, B A, ...) so
that a change of load during the run hits both alike.
"""

from __future__ import annotations

import contextlib
import io
import os
import subprocess
import tarfile
import tempfile
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

from results import ROOT, commit

PACKAGE = "tactile_sensor/tactile_sensor"  # the Python package inside the colcon package


class CompareError(Exception):
    """The revision to compare with cannot be used; the message says why and what to do."""


@dataclass(frozen=True)
class Variant:
    """One version of the nodes: a label for the tables and the folder holding its
    ``tactile_sensor`` package (first on PYTHONPATH)."""

    label: str
    source: Path

    def env(self, base: dict[str, str] | None = None) -> dict[str, str]:
        """The environment that runs this version's modules (``python -m ...``)."""
        env = dict(os.environ if base is None else base)
        env["PYTHONPATH"] = f"{self.source}:{env.get('PYTHONPATH', '')}"
        return env


#: Every driver of a side-by-side run reads this checkout's mock hardware.
MOCK = Variant("mock", ROOT / "tactile_sensor")
#: How long a node may take to its first 2,000 readings: a loaded 2-core machine took over
#: 60 s.
WARM_UP_S = 120


def _git(*args: str) -> subprocess.CompletedProcess[bytes]:
    return subprocess.run(["git", "-C", str(ROOT), *args], capture_output=True, check=False)


def resolve(rev: str) -> str:
    """The short hash of ``rev``, or ``CompareError`` naming it."""
    done = _git("rev-parse", "--short", "--verify", "--quiet", f"{rev}^{{commit}}")
    if done.returncode or not done.stdout.strip():
        raise CompareError(f"--compare {rev!r} is not a commit of this repository; give a "
                           "hash, branch or tag that 'git log --oneline' shows.")
    return done.stdout.decode().strip()


@contextlib.contextmanager
def variants(compare: str | None) -> Iterator[list[Variant]]:
    """[this checkout] or, with ``compare``, [that commit, this checkout]."""
    this = Variant(f"this ({commit()})", ROOT / "tactile_sensor")
    if compare is None:
        yield [this]
        return
    rev = resolve(compare)
    archive = _git("archive", "--format=tar", rev, PACKAGE)
    if archive.returncode:
        raise CompareError(f"commit {rev} has no {PACKAGE} to run "
                           f"({archive.stderr.decode().strip()}); compare with a later one.")
    with tempfile.TemporaryDirectory(prefix=f"bench_{rev}_") as tmp:
        with tarfile.open(fileobj=io.BytesIO(archive.stdout)) as tar:
            tar.extractall(tmp, filter="data")
        yield [Variant(rev, Path(tmp) / "tactile_sensor"), this]


def interleaved(items: Sequence[Variant], rounds: int) -> Iterator[tuple[int, Variant]]:
    """(round, variant) with the order reversed every other round."""
    for r in range(rounds):
        for item in (items if r % 2 == 0 else list(reversed(items))):
            yield r, item


def cpu_seconds(pid: int) -> float:
    """User + system CPU time of process ``pid`` so far [s]."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def load_average() -> float:
    """The 1-minute load average: what else the machine was doing."""
    return os.getloadavg()[0]
