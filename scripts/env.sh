# Source me: the venv and the built workspace of one distribution (DISTRO=jazzy|kilted,
# default jazzy; or the sourced ROS 2), with ROS traffic kept on this machine.
# shellcheck source=scripts/distro.sh
. "$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)/distro.sh" || return 2
if [ ! -f "$TS_INSTALL/setup.bash" ]; then
  echo "the $TS_TAG workspace is not built: run 'make setup DISTRO=$DISTRO'." >&2
  return 2 2>/dev/null || exit 2
fi
# shellcheck disable=SC1091
. "$TS_VENV/bin/activate"
if [ -z "${ROS_DISTRO:-}" ]; then
  export AMENT_PREFIX_PATH="${AMENT_PREFIX_PATH:-$VIRTUAL_ENV}"
fi
# colcon's setup scripts reference unset variables; source them leniently.
_ts_u=$(set +o | grep nounset); set +u
# shellcheck disable=SC1091
. "$TS_INSTALL/setup.bash"
eval "$_ts_u"
export ROS_AUTOMATIC_DISCOVERY_RANGE="${ROS_AUTOMATIC_DISCOVERY_RANGE:-LOCALHOST}"
unset _ts_u
