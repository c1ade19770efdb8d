"""Whether this shell has what the ROS-installation tests need: ``ros2 launch``, the ``ros2``
command line, ``launch`` and ``launch_ros``. The PyPI wheels carry none of them; a sourced
ROS 2 installation has all. conftest.py skips those tests where one is missing, and
``make test-ros2`` runs this file first (``python3 tactile_sensor/test/ros2_tools.py``), so
it refuses in one sentence before setting anything up. Imports no pytest: it runs before
setup has made a venv.
"""

from __future__ import annotations

import importlib
import importlib.util
import os
import shutil
import sys

#: The command that runs exactly these tests.
COMMAND = "make test-ros2"
#: The ``ros2 launch`` argument for how long it waits after SIGINT before escalating a node
#: to SIGTERM (launch's default: 5 s). The tests judge that no node needed the escalation,
#: not how fast a busy machine stops them: beside a core at a load of 20, every node of a
#: bench launch took over 5 s to exit on SIGINT, and did so on its own.
SIGTERM_PATIENCE = "sigterm_timeout:=30"


def ros2_tools_missing() -> str | None:
    """What of the ROS 2 tools this shell lacks, as a phrase (None: nothing)."""
    missing = [what for what, present in (
        ("the ros2 command", shutil.which("ros2")),
        ("the launch package", _importable("launch", "LaunchDescription")),
        ("launch_ros", _importable("launch_ros", "actions")),
    ) if not present]
    if not missing:
        return None
    return missing[0] if len(missing) == 1 else f"{', '.join(missing[:-1])} and {missing[-1]}"


def skip_reason(missing: str) -> str:
    """The reason each such test is skipped; the summary counts the tests under it."""
    return (f"needs {missing}, which the PyPI-wheels path lacks: '{COMMAND}' runs these "
            "tests in a shell with a ROS 2 installation sourced (docs/testing.md)")


def refusal(missing: str) -> str:
    """``make test-ros2``'s one sentence where the tools are missing."""
    distro = os.environ.get("DISTRO") or "jazzy"
    return (f"{COMMAND}: this shell lacks {missing}: source a ROS 2 installation "
            f"(e.g. '. /opt/ros/{distro}/setup.bash'; the PyPI wheels have none of them) and "
            "run it again.")


def _importable(module: str, attribute: str) -> bool:
    """The real package, not a namespace package made of a folder of ours of the same name
    (tactile_sensor/launch/ is on sys.path in tests)."""
    try:
        return importlib.util.find_spec(f"{module}.{attribute}") is not None or hasattr(
            importlib.import_module(module), attribute)
    except ImportError:
        return False


if __name__ == "__main__":
    what = ros2_tools_missing()
    if what:
        print(refusal(what), file=sys.stderr)
    sys.exit(2 if what else 0)
