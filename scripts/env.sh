# Source me: the venv and the built workspace, with ROS traffic kept on this machine.
_ts_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# shellcheck disable=SC1091
. "$_ts_root/.venv/bin/activate"
if [ -z "${ROS_DISTRO:-}" ]; then
  export AMENT_PREFIX_PATH="${AMENT_PREFIX_PATH:-$VIRTUAL_ENV}"
fi
# colcon's setup scripts reference unset variables; source them leniently.
_ts_u=$(set +o | grep nounset); set +u
# shellcheck disable=SC1091
. "$_ts_root/install/setup.bash"
eval "$_ts_u"
export ROS_AUTOMATIC_DISCOVERY_RANGE="${ROS_AUTOMATIC_DISCOVERY_RANGE:-LOCALHOST}"
unset _ts_root _ts_u
