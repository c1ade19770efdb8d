#!/usr/bin/env bash
# The README's test command (via 'make test'): set up if needed, lint, then pytest over the
# workspace with ROS isolated to this machine and to this run.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
bash scripts/setup.sh
# shellcheck disable=SC1091
. scripts/env.sh
echo "[test] ruff check" >&2
ruff check .
# A run-unique block of domain ids: each test takes its own from it (tactile_sensor/test/conftest.py).
# TACTILE_TEST_DOMAIN_BASE set by the caller wins (several checkouts testing at once).
base=${TACTILE_TEST_DOMAIN_BASE:-$(( (RANDOM % 9) * 10 + 20 ))}
export TACTILE_TEST_DOMAIN_BASE="$base" ROS_DOMAIN_ID="$base"
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
export MPLBACKEND=Agg
export XDG_CACHE_HOME="${XDG_CACHE_HOME:-$ROOT/.cache}"
# Tests that start processes mostly wait (DDS discovery, protocols at device pace), so
# pytest-xdist workers overlap their waits; each worker takes whole files (module fixtures
# are built once) and its own share of the domain ids (conftest.py: worker_domains). One
# starts with the device-paced protocol files, one after the other, while the other runs the
# rest beside them (conftest.py: protocol_lane_scheduling). A third worker starves the
# real-time tests beside a busy core (a gripper's closed loop, a reader's buffer).
workers=${TACTILE_TEST_WORKERS:-2}
xdist=()
# --no-loadscope-reorder: files in the order conftest.py sorts them (longest first), not by
# their number of tests.
[ "$workers" -gt 1 ] && xdist=(-n "$workers" --dist loadfile --no-loadscope-reorder)
echo "[test] pytest on ROS 2 $DISTRO (ROS_DOMAIN_ID base $base, localhost discovery," \
  "$workers worker(s))" >&2
# A rerun attempt's failure is printed too, so a flaky test shows why it failed.
exec python -m pytest "${xdist[@]}" --rerun-show-tracebacks "$@"
