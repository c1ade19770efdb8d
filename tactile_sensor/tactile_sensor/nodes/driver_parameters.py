"""The driver's parameters: names, defaults, units and ranges (``ros2 param describe``),
in one list apart from the node, so that nodes/driver.py reads as wiring."""

from __future__ import annotations

from tactile_sensor.hardware.adc_reader import DEFAULT_BACKLOG
from tactile_sensor.nodes.parameters import ParamSpec
from tactile_sensor.sensing.array_chain import TORQUE_CUTOFF_HZ, parse_modules
from tactile_sensor.sensing.bend_chain import parse_bend_modules
from tactile_sensor.sensing.errors import SensingError
from tactile_sensor.sensing.filters import DEFAULT_FILTER, FILTERS
from tactile_sensor.sensing.live_force import DEFAULT_WINDOW_S as DEFAULT_LIVE_WINDOW_S
from tactile_sensor.sensing.rest_gain import (
    DEFAULT_GAIN_BOUND,
    DEFAULT_RETARE_TIME_CONSTANT_S,
    MAX_RETARE_TIME_CONSTANT_S,
)

#: Two samples a read at 1 kHz (bench_driver.py measures the driver's CPU with it).
DEFAULT_READ_PERIOD_S = 0.002


def _modules_problem(text: str) -> str | None:
    try:
        parse_modules(text)
    except SensingError as exc:
        return str(exc)
    return None


def _bend_modules_problem(text: str) -> str | None:
    if not text.strip():
        return None
    try:
        parse_bend_modules(text)
    except SensingError as exc:
        return str(exc)
    return None


SPECS = [
    ParamSpec("port", "/dev/ttyACM0", "serial device of the ADC (path or pyserial URL)"),
    ParamSpec("baud_rate", 1_000_000, "serial baud rate [bit/s] the firmware uses",
              minimum=50, maximum=12_000_000),
    ParamSpec("channel", 0, "ADC channel wired to the photoreflector", minimum=0, maximum=7),
    ParamSpec("modules", "", "module array as CHANNEL:FACE pairs, e.g. '0:front,1:back,2:left,"
              "3:right' (faces front +y, back -y, left -x, right +x), a window off the "
              "face's centre as CHANNEL:FACE@OFFSET with the offset along the face in metres "
              "(e.g. '0:front@-0.0055,1:front@0.0055,...'): ~/wrench then carries force "
              "x, y, z in N and torque x, y, z in N m from an array calibration, NaN for "
              "the components it does not observe; empty = one module on 'channel'",
              check=_modules_problem),
    ParamSpec("bend_modules", "", "a bending finger's modules as CHANNEL:PLACE, PLACE joint "
              "(over the joint) or tip (at the fingertip), e.g. '0:joint,1:tip': "
              "~/joint_states carries the joint angle in rad (NaN beyond the calibration's "
              "range) and ~/wrench force.z the fingertip's contact force in N, NaN with the "
              "joint module alone (it cannot tell a contact from a bend); empty = not a "
              "finger", check=_bend_modules_problem),
    ParamSpec("joint_name", "finger_joint", "name of the finger's joint in ~/joint_states"),
    ParamSpec("bend_cache_dir", "", "cache folder of the finger's FEM table (bend_modules "
              "with calibration_source model); empty = default"),
    ParamSpec("torque_cutoff_hz", TORQUE_CUTOFF_HZ, "cutoff [Hz] of the 2nd-order "
              "Butterworth low-pass on the array's torque (after the calibration); 10 Hz "
              "because the torque is a small difference of module outputs and its noise "
              "grows with the square root of this bandwidth; below half sample_rate",
              minimum=0.0, exclusive_minimum=True, maximum=200.0),
    ParamSpec("adc_bits", 0, "ADC resolution [bit]; 0 = as the device states (protocol 2); "
              "a value the device contradicts is an error", minimum=0, maximum=16),
    ParamSpec("reference_voltage", 0.0, "ADC reference voltage [V] (full scale); 0 = as the "
              "device states (protocol 2); a value the device contradicts is an error",
              minimum=0.0, maximum=50.0),
    ParamSpec("sample_rate", 1000.0, "nominal device sample rate [Hz] the filters and tare "
              "window are designed for", minimum=0.0, exclusive_minimum=True,
              maximum=100_000.0),
    ParamSpec("filter_type", DEFAULT_FILTER, "filter on every sample; the default "
              "'savgol_mains' is 'savgol' until it finds a lamp's 100 or 120 Hz flicker, then "
              "also nulls it and its harmonics (half a flicker period of delay, 4.5 ms at "
              "100 Hz)", choices=tuple(FILTERS)),
    ParamSpec("filter.window", 0, "window [samples] of savgol, savgol_mains, "
              "savgol_quadratic, savgol_quadratic_mains or moving_average; 0 = the filter's "
              "default (40, 40, 100, 100 or 9)", minimum=0, maximum=100_000),
    ParamSpec("filter.cutoff_hz", 50.0, "butterworth cutoff [Hz]", minimum=0.0,
              exclusive_minimum=True),
    ParamSpec("filter.order", 2, "butterworth order", minimum=1, maximum=8),
    ParamSpec("filter.min_cutoff_hz", 10.0, "one_euro minimum cutoff [Hz]", minimum=0.0,
              exclusive_minimum=True),
    ParamSpec("filter.beta", 0.5, "one_euro speed coefficient [1/V]", minimum=0.0),
    ParamSpec("filter.d_cutoff_hz", 1.0, "one_euro derivative cutoff [Hz]", minimum=0.0,
              exclusive_minimum=True),
    ParamSpec("publish_rate", 0.0, "rate [Hz] of ~/wrench, the live force; 0 = every "
              "sample (~/reading, the record, and the filter always get every sample)",
              minimum=0.0, maximum=100_000.0),
    ParamSpec("live_window", DEFAULT_LIVE_WINDOW_S, "~/wrench carries the readings within "
              "this much of the newest sample [s]: a driver behind its ADC (a busy machine) "
              "skips the older ones there, counted in /diagnostics 'wrench_skipped'; "
              "~/reading still carries every one", minimum=0.0, maximum=10.0),
    ParamSpec("frame_id", "tactile_sensor", "frame of the wrench; +z is the skin normal "
              "pointing into the sensor"),
    ParamSpec("calibration_source", "model", "where output->force comes from: 'model' "
              "(latched curve on calibration_curve; with modules, the latched "
              "array_calibration) or 'file'", choices=("model", "file")),
    ParamSpec("calibration_file", "", "calibration JSON written by 'tactile-sensor "
              "analyze --fit-calibration', with modules an array calibration written by "
              "'tactile-sensor model array-calibration --calibration' (calibration_source: "
              "file)"),
    ParamSpec("contact_on_force", 0.5, "contact when the force rises above this [N]",
              minimum=0.0, exclusive_minimum=True),
    ParamSpec("contact_off_force", 0.3, "contact ends when the force falls below this [N]",
              minimum=0.0),
    ParamSpec("contact_debounce", 0.01, "a contact change must persist this long [s]",
              minimum=0.0, maximum=10.0),
    ParamSpec("tare_window", 0.5, "tare averages this much signal at rest [s]",
              minimum=0.0, exclusive_minimum=True, maximum=60.0),
    ParamSpec("tare_max_spread", 0.05, "tare is refused if the voltage spread in the window "
              "exceeds this [V] (not at rest)", minimum=0.0, exclusive_minimum=True),
    ParamSpec("auto_tare", True, "tare by itself on the first window found at rest"),
    ParamSpec("rest_retare_time_constant", DEFAULT_RETARE_TIME_CONSTANT_S, "re-tare at rest: "
              "while sure nothing touches the skin (a whole tare_window without contact, the "
              "force under contact_off_force, the detector not blind, the level within "
              "tare_max_spread) the baseline follows the level with this time constant [s], "
              "so slow changes of light and of the emitter are followed; a press that stays "
              "under contact_off_force this long is taken for light; 0 = re-tare only on "
              "~/tare and the first auto_tare (single module)", minimum=0.0,
              maximum=MAX_RETARE_TIME_CONSTANT_S),
    ParamSpec("gain_tracking", True, "modulated module: read the calibration at the optical "
              "gain measured at rest (the emitter's drop against the one when the "
              "calibration arrived), so the sensitivity holds as the emitter dims or warms; "
              "a stock module cannot measure it (its drop at rest holds the room's light)"),
    ParamSpec("gain_warn_bound", DEFAULT_GAIN_BOUND, "/diagnostics warns 'recalibrate' once "
              "the optical gain is off its calibration's by more than this fraction [1] "
              "(0.15 = +-15 %)", minimum=0.0, exclusive_minimum=True, maximum=0.99),
    ParamSpec("reader_backlog", DEFAULT_BACKLOG, "samples read from the port but not yet "
              "processed that the driver may hold while starved of CPU; beyond it new ones "
              "are dropped and counted (diagnostics 'frames_overflowed')", minimum=1,
              maximum=10_000_000),
    ParamSpec("read_period", DEFAULT_READ_PERIOD_S, "the port is read at most once this "
              "often [s]: at 1 kHz a read then brings a few samples for one wake-up of the "
              "reader's thread (the driver's CPU); the live force waits up to this long "
              "more; 0 = read each sample as it arrives", minimum=0.0, maximum=0.1),
    ParamSpec("diagnostics_period", 1.0, "period of /diagnostics [s] (also sent at once on "
              "a connection change)", minimum=0.05, maximum=60.0),
]

SPEC_BY_NAME = {spec.name: spec for spec in SPECS}
