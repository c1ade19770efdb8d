# Source me: which ROS 2 distribution this workspace runs on, and where its venv and build live.
# DISTRO=jazzy (default, the LTS) or kilted picks the PyPI wheels; with a ROS 2 installation
# sourced, ROS_DISTRO names it and the folders get a '-sourced' suffix, so a wheels venv and a
# sourced build of the same distribution never share a folder.
_ts_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
if [ -n "${ROS_DISTRO:-}" ]; then
  if [ -n "${DISTRO:-}" ] && [ "$DISTRO" != "$ROS_DISTRO" ]; then
    echo "DISTRO=$DISTRO but ROS 2 '$ROS_DISTRO' is sourced: unset DISTRO or source the" \
      "$DISTRO installation." >&2
    return 2 2>/dev/null || exit 2
  fi
  DISTRO="$ROS_DISTRO"
  TS_TAG="$ROS_DISTRO-sourced"
else
  DISTRO="${DISTRO:-jazzy}"
  case "$DISTRO" in
    jazzy|kilted) ;;
    *)
      echo "DISTRO=$DISTRO is not one we test: use DISTRO=jazzy (the LTS) or DISTRO=kilted," \
        "or source a ROS 2 installation." >&2
      return 2 2>/dev/null || exit 2
      ;;
  esac
  TS_TAG="$DISTRO"
fi
export DISTRO
TS_VENV="$_ts_root/.venv/$TS_TAG"
TS_BUILD="$_ts_root/build/$TS_TAG"
TS_INSTALL="$_ts_root/install/$TS_TAG"
TS_LOG="$_ts_root/log/$TS_TAG"
unset _ts_root
