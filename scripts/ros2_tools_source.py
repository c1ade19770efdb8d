#!/usr/bin/env python3
"""Find (or fetch) the upstream sources of launch, launch_ros, the ros2 CLI and control_msgs.

PyPI's ROS 2 wheels lack these pure-Python tools, so ``scripts/setup.sh`` builds them with
colcon beside our packages. Prints the source folder on stdout, or one sentence on stderr and
exit status 1 when there is none, so setup can go on without them.

Order: ``$ROS2_TOOLS_SRC``; ``../shared/ros2-src`` beside the repository; a clone of
``requirements/ros2-tools.repos`` at its pinned commits into ``build/ros2-tools-src`` (network
needed; the clone is reused while the commits are unchanged). Of the cloned repositories only
the packages listed in ``KEPT`` are built; the rest get a ``COLCON_IGNORE``.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import yaml

KEPT = frozenset({
    "launch", "launch_xml", "launch_yaml", "launch_ros", "ros2launch",
    "ros2cli", "ros2pkg", "ros2run", "ros2node", "ros2topic", "ros2service", "ros2action",
    "ros2lifecycle", "ros2param", "ros2interface", "rosidl_runtime_py",
    "composition_interfaces", "control_msgs",
})
GIT_TIMEOUT_S = 300.0


class SourceError(Exception):
    """No usable source folder; the message is one sentence for the user."""


def read_repos(repos_file: Path) -> dict[str, tuple[str, str]]:
    """Name -> (url, commit) from a vcstool ``.repos`` file."""
    try:
        data = yaml.safe_load(repos_file.read_text())
        return {
            name: (str(entry["url"]), str(entry["version"]))
            for name, entry in data["repositories"].items()
        }
    except (OSError, yaml.YAMLError, KeyError, TypeError, AttributeError) as exc:
        raise SourceError(f"{repos_file} is not a readable vcstool repos file ({exc}).") from None


def _git(args: list[str], cwd: Path) -> None:
    env = dict(os.environ, GIT_TERMINAL_PROMPT="0")
    try:
        subprocess.run(
            ["git", *args], cwd=cwd, env=env, check=True, timeout=GIT_TIMEOUT_S,
            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
        )
    except FileNotFoundError:
        raise SourceError("git is not installed.") from None
    except subprocess.TimeoutExpired:
        raise SourceError(f"git {args[0]} took longer than {GIT_TIMEOUT_S:.0f} s.") from None
    except subprocess.CalledProcessError as exc:
        last = (exc.stderr or "").strip().splitlines()[-1:] or ["no message"]
        raise SourceError(f"git {args[0]} failed in {cwd}: {last[0]}") from None


def clone(repos: dict[str, tuple[str, str]], dest: Path) -> Path:
    """Shallow-fetch each repository at its commit; a folder already at that commit is kept."""
    dest.mkdir(parents=True, exist_ok=True)
    for name, (url, commit) in repos.items():
        folder = dest / name
        marker = folder / ".tactile-commit"
        if marker.is_file() and marker.read_text().strip() == commit:
            continue
        folder.mkdir(exist_ok=True)
        _git(["init", "-q"], folder)
        _git(["fetch", "-q", "--depth", "1", url, commit], folder)
        _git(["checkout", "-q", "--force", "FETCH_HEAD"], folder)
        for package_xml in folder.rglob("package.xml"):
            if package_xml.parent.name not in KEPT:
                (package_xml.parent / "COLCON_IGNORE").touch()
        marker.write_text(commit + "\n")
    return dest


def find_source(root: Path, environ: dict[str, str]) -> Path:
    """The folder setup should add to colcon's base paths."""
    configured = environ.get("ROS2_TOOLS_SRC")
    if configured:
        path = Path(configured)
        if not path.is_dir():
            raise SourceError(f"ROS2_TOOLS_SRC={configured} is not a folder; unset it or fix it.")
        return path
    shared = root.parent / "shared" / "ros2-src"
    if shared.is_dir():
        return shared
    return clone(read_repos(root / "requirements" / "ros2-tools.repos"),
                 root / "build" / "ros2-tools-src")


def main(argv: list[str]) -> int:
    root = Path(argv[1] if len(argv) > 1 else Path(__file__).resolve().parents[1]).resolve()
    try:
        print(find_source(root, dict(os.environ)))
    except SourceError as exc:
        print(f"[setup] {exc}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
