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
# A domain of this checkout and distribution of its own (1-100, from the venv's path) unless
# one is set: every shell of one checkout meets the same nodes, another checkout's seldom
# (docs/install.md).
if [ -z "${ROS_DOMAIN_ID:-}" ]; then
  ROS_DOMAIN_ID=$(( $(printf '%s' "$TS_VENV" | cksum | cut -d' ' -f1) % 100 + 1 ))
  export ROS_DOMAIN_ID
fi
unset _ts_u
