"""`rosdep install --from-paths src --ignore-src` resolves every key, as a robot would.

Checked offline against a snapshot of rosdistro's own rosdep database and distribution
files (``../shared/rosdistro``, or ``$TACTILE_ROSDISTRO``) plus the project's
``rosdep/tactile_sensor.yaml``, for Jazzy and Kilted on Ubuntu Noble. On this Debian host
the apt packages are of course not installed, so "not satisfied" lines are expected; what
must never appear is a key that does not resolve.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[3]
ROSDISTRO = Path(os.environ.get("TACTILE_ROSDISTRO", REPO.parent / "shared" / "rosdistro"))
PROJECT_KEYS = REPO / "rosdep" / "tactile_sensor.yaml"
# rosdep2.main has no __main__ guard for ``-m``: call its entry point.
ROSDEP = [sys.executable, "-c",
          "import sys; from rosdep2.main import rosdep_main; rosdep_main(sys.argv[1:])"]

pytestmark = [pytest.mark.skipif(
    not (ROSDISTRO / "index-v4.yaml").is_file(),
    reason=f"no rosdistro snapshot at {ROSDISTRO} (set TACTILE_ROSDISTRO)",
), pytest.mark.slow]  # rosdep runs as a process


def _rosdep(tmp: Path, sources: list[Path], distro: str, *args: str) -> subprocess.CompletedProcess:
    lists = tmp / "sources.list.d"
    lists.mkdir(exist_ok=True)
    (lists / "20-default.list").write_text(
        "".join(f"yaml file://{source.resolve()}\n" for source in sources))
    # Without the workspace's prefixes: --ignore-src would otherwise skip every ROS package
    # the wheels provide, and the check would say nothing about their keys.
    env = {key: value for key, value in os.environ.items()
           if key not in {"AMENT_PREFIX_PATH", "CMAKE_PREFIX_PATH", "COLCON_PREFIX_PATH",
                          "ROS_PACKAGE_PATH"}}
    env.update(ROSDEP_SOURCE_PATH=str(lists), ROS_HOME=str(tmp / "home"),
               ROSDISTRO_INDEX_URL=f"file://{ROSDISTRO.resolve()}/index-v4.yaml")
    update = subprocess.run([*ROSDEP, "update", "--rosdistro", distro], env=env,
                            capture_output=True, text=True, timeout=120)
    assert update.returncode == 0, update.stdout + update.stderr
    return subprocess.run(
        [*ROSDEP, "check", "--from-paths", *args, "--ignore-src", "--rosdistro", distro,
         "--os", "ubuntu:noble"],
        env=env, capture_output=True, text=True, timeout=120)


SOURCES = [str(REPO / "tactile_sensor"), str(REPO / "tactile_sensor_interfaces")]


def _unresolved(result: subprocess.CompletedProcess) -> list[str]:
    text = result.stdout + result.stderr
    return [line for line in text.splitlines()
            if "Cannot locate rosdep definition" in line or line.startswith("ERROR")]


DEFAULT = [ROSDISTRO / "rosdep" / "base.yaml", ROSDISTRO / "rosdep" / "python.yaml"]


@pytest.mark.parametrize("distro", ["jazzy", "kilted"])
def test_every_key_resolves_with_the_project_file(tmp_path: Path, distro: str) -> None:
    result = _rosdep(tmp_path, [*DEFAULT, PROJECT_KEYS], distro, *SOURCES)
    assert _unresolved(result) == [], result.stdout + result.stderr
    # Resolved, and listed as not installed on this host (a robot with them installed
    # passes the check outright).
    assert f"ros-{distro}-rclpy" in result.stdout or result.returncode == 0, result.stdout


def test_without_the_project_file_the_pip_keys_do_not_resolve(tmp_path: Path) -> None:
    """The check can fail: rosdistro alone lacks the keys the project file adds."""
    result = _rosdep(tmp_path, DEFAULT, "jazzy", *SOURCES)
    unresolved = _unresolved(result)
    assert unresolved, result.stdout + result.stderr
    project_keys = PROJECT_KEYS.read_text()
    for line in unresolved:
        key = line.split("[")[-1].rstrip("]")
        assert f"\n{key}:" in project_keys, line
