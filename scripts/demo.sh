#!/usr/bin/env bash
# The README's main job: run a configuration on mock hardware, record it, and (bench)
# analyse the recording against the paper's figures.
#   scripts/demo.sh bench [PROTOCOL]   (default demo: every paper speed in a minute)
#   scripts/demo.sh gripper
#   scripts/demo.sh rate [SPEEDS_PROTOCOL]   (default speeds:cycles=1,hold=2)
#   scripts/demo.sh wrench [WRENCH_PROTOCOL]   (default wrench)
#   scripts/demo.sh ambient
#   scripts/demo.sh lift
#   scripts/demo.sh bend
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

# NAME's PROTOCOL (a configuration) on mock hardware recorded into BAG, its ADC on pty ADC.
record() {
  local name="$1" protocol="$2" bag="$3" adc="$4"
  echo "== $name '$protocol' on mock hardware -> $bag"
  tactile-sensor bringup "$name" --protocol "$protocol" --record "$bag" \
    --port "adc_port=/tmp/tactile_sensor/${adc}_$$"
}

# The recording in $run/bag analysed into $run/analysis (more analyze options may follow).
analyse() {
  echo "== analysing $run/bag"
  tactile-sensor analyze "$run/bag" --out "$run/analysis" "$@"
}

show_figures() {
  echo "== plots"
  ls -1 "$run"/analysis/*.png
  echo "== report: $run/analysis/report.md, metrics: $run/analysis/metrics.json"
}

case "$configuration" in
  bench)
    # 'demo': Figs 7-9 from 12 presses at 0.1, 1 and 10 mm/s in about a minute; every
    # figure with its 95 % interval over the cycles (docs/analysis-metrics.md)
    record bench "${2:-demo}" "$run/bag" demo_adc
    analyse
    echo "== the paper's figures beside the measured ones (± 95 % interval over the cycles)"
    grep '^|' "$run/analysis/report.md"
    show_figures
    ;;
  rate)
    # Calibration across indentation speeds: fit the rate-aware model on 'speeds', then run
    # speeds it never saw (rate_check) with the fitted file in the driver, and compare.
    record bench "${2:-speeds:cycles=1,hold=2}" "$run/speeds" demo_adc
    echo "== fitting the static curve and the rate terms -> $run/fit/calibration.json"
    tactile-sensor analyze "$run/speeds" --out "$run/fit" --fit-calibration
    cat > "$run/driver.yaml" <<YAML
/**/driver:
  ros__parameters:
    calibration_source: file
    calibration_file: $ROOT/$run/fit/calibration.json
YAML
    echo "== bench 'rate_check' (0.3, 3, 20 mm/s with holds) with the fitted file -> $run/check"
    tactile-sensor bringup bench --protocol rate_check --record "$run/check" \
      --config "$run/driver.yaml" --port "adc_port=/tmp/tactile_sensor/demo_adc_$$"
    echo "== static against rate-aware on the held-out speeds"
    tactile-sensor analyze "$run/check" --out "$run/check-analysis" \
      --calibration "$run/fit/calibration.json"
    sed -n '/[Rr]ate/,$p' "$run/check-analysis/report.md"
    echo "== report: $run/check-analysis/report.md"
    ;;
  wrench)
    # Six-axis wrench: press, shear, tilt, twist and combine them on the 8-module layout, then
    # compare the driver's force and torque with the six-component gauge.
    record wrench "${2:-wrench}" "$run/bag" demo_wadc
    analyse --quiet
    echo "== the six errors (rmse against the gauge, in % of each component's range)"
    python - "$run/analysis/metrics.json" <<'PY'
import json
import sys

m = json.load(open(sys.argv[1]))
for kind, unit in (("force", "n"), ("torque", "nm")):
    rmse, span = m.get(f"{kind}_rmse_{unit}") or {}, m.get(f"{kind}_range_{unit}") or {}
    for axis in "xyz":
        r, s = rmse.get(axis), span.get(axis)
        label = f"{kind[0].upper()}{axis}"
        if r is None or not s:
            print(f"  {label}: not estimated")
        else:
            name = "N" if unit == "n" else "N m"
            print(f"  {label}: rmse {r:.4g} {name} over a {s:.4g} {name} range = "
                  f"{100 * r / s:.1f} %")
found = m.get("wrench_excursions") or {}
print("== gains per excursion (estimate on gauge where |gauge| > 25 % of its peak; goal "
      "0.85-1.15)")
for name in ("fx", "fy", "fz", "tx", "ty", "tz"):
    gains = [x["gain"] for x in found.get(name, [])]
    if gains:
        print(f"  {name.capitalize()}: " + ", ".join("NaN" if g is None else f"{g:.2f}"
                                                    for g in gains))
worst = found.get("worst_gain")
print(f"  worst gain: {'none' if worst is None else f'{worst:.2f}'}")
rest = found.get("rest_noise") or {}
print(f"== noise at rest (standard deviation where the gauge reads no load, "
      f"{rest.get('samples', 0)} samples)")
for name in ("fx", "fy", "fz", "tx", "ty", "tz"):
    value = rest.get(name)
    if value is not None:
        scale, unit = (1e3, "mN") if name[0] == "f" else (1e3, "mN m")
        print(f"  {name.capitalize()}: {value * scale:.2f} {unit}")
PY
    show_figures
    ;;
  ambient)
    # Outside the dark room (docs/ambient.md): the ambient protocol's presses on the mock's
    # physics under each light scenario and drift, through today's driver and through the
    # driver following each kind of module at rest, side by side (about a minute).
    echo "== force error: dark room, light and drift; today's driver beside each kind of module"
    python benchmarks/bench_ambient.py --demo | tee "$run/ambient.txt"
    echo "== table: $run/ambient.txt"
    ;;
  lift)
    # An object lifted, then its load doubled (docs/gripper.md, "The lift protocol"): a
    # fixed grasp at the adaptive hold's starting force beside the adaptive hold, three
    # objects, through the real nodes on the mock (1-3 minutes).
    echo "== slip with the load doubled: fixed grasp beside adaptive hold"
    python benchmarks/bench_lift.py --demo | tee "$run/lift.txt"
    echo "== table: $run/lift.txt"
    ;;
  bend)
    # The bending finger (docs/bend.md): a slow sweep 0-90 deg, bends at 0.2, 0.5 and 1 Hz,
    # and 0.5 Hz bends with a fingertip contact up to 0.5 N (the FEM's limit), read by the
    # joint and fingertip modules; then the contact run again with the joint module alone.
    # Each recording is analysed against the mock's true angle (a few minutes; a first run
    # computes the FEM).
    for protocol in sweep speeds contact; do
      record bend "$protocol" "$run/$protocol" demo_badc
      echo "== $protocol: the driver's joint angle against the truth (two modules)"
      tactile-sensor analyze "$run/$protocol" --out "$run/$protocol-analysis" 2>&1 \
        | sed -n 's/^bend: /  /p'
    done
    cat > "$run/one-module.yaml" <<YAML
/**/bend:
  ros__parameters:
    bend.modules: joint
/**/driver:
  ros__parameters:
    bend_modules: "0:joint"
YAML
    echo "== bend 'contact' with the joint module alone -> $run/contact-one"
    tactile-sensor bringup bend --protocol contact --record "$run/contact-one" \
      --config "$run/one-module.yaml" --port "adc_port=/tmp/tactile_sensor/demo_badc_$$"
    echo "== contact: the driver's joint angle against the truth (one module: force NaN)"
    tactile-sensor analyze "$run/contact-one" --out "$run/contact-one-analysis" 2>&1 \
      | sed -n 's/^bend: /  /p'
    echo "== plots"
    ls -1 "$run"/*-analysis/*.png
    echo "== reports: $run/*-analysis/report.md"
    ;;
  gripper)
    echo "== gripper grasp/hold/release on mock hardware -> $run/bag"
    tactile-sensor bringup gripper --protocol grasp --record "$run/bag" \
      --port "adc_port=/tmp/tactile_sensor/demo_gadc_$$" \
      --port "servo_port=/tmp/tactile_sensor/demo_xm430_$$"
    ;;
  *)
    echo "usage: scripts/demo.sh bench [demo|compression|repeatability|speeds] | gripper |" \
      "rate [SPEEDS_PROTOCOL] | wrench [WRENCH_PROTOCOL] | ambient | lift | bend" >&2
    exit 2
    ;;
esac
