#!/usr/bin/env bash
# The README's main job: run a configuration on mock hardware, record it, and (bench)
# analyse the recording against the paper's figures.
#   scripts/demo.sh bench [PROTOCOL]   (default compression)
#   scripts/demo.sh gripper
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
# shellcheck disable=SC1091
. scripts/env.sh
export ROS_DOMAIN_ID="${ROS_DOMAIN_ID:-$(( RANDOM % 100 + 120 ))}"
export MPLBACKEND=Agg
configuration="${1:-bench}"
run="demo-out/${configuration}-$(date +%Y%m%d-%H%M%S)"
mkdir -p "$run"
mkdir -p /tmp/tactile_sensor
case "$configuration" in
  bench)
    protocol="${2:-compression}"
    echo "== bench '$protocol' on mock hardware -> $run/bag"
    tactile-sensor bringup bench --protocol "$protocol" --record "$run/bag" \
      --port "adc_port=/tmp/tactile_sensor/demo_adc_$$"
    echo "== analysing $run/bag"
    tactile-sensor analyze "$run/bag" --out "$run/analysis"
    echo "== the paper's figures beside the measured ones"
    grep '^|' "$run/analysis/report.md"
    echo "== plots"
    ls -1 "$run"/analysis/*.png
    echo "== report: $run/analysis/report.md, metrics: $run/analysis/metrics.json"
    ;;
  gripper)
    echo "== gripper grasp/hold/release on mock hardware -> $run/bag"
    tactile-sensor bringup gripper --protocol grasp --record "$run/bag" \
      --port "adc_port=/tmp/tactile_sensor/demo_gadc_$$" \
      --port "servo_port=/tmp/tactile_sensor/demo_xm430_$$"
    ;;
  *)
    echo "usage: scripts/demo.sh bench [compression|repeatability|speeds] | gripper" >&2
    exit 2
    ;;
esac
