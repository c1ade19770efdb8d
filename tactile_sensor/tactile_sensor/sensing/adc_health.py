"""What the driver's diagnostics say about its ADC stream, without ROS.

Priority of the one-sentence message: the connection first, then the device's info frame
and whether it contradicts the configuration, then a detector blinded by light, then tare
and calibration, then an optical gain past its bound ("recalibrate"), then frames lost
since the last report. Lost frames are also counted here so they are never silent: each
report names how many went missing since the previous one.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Mapping

from tactile_sensor.hardware.adc_reader import ConnectionState, ReaderStats
from tactile_sensor.hardware.health import Health, Level
from tactile_sensor.sensing.adc_settings import AdcSettings
from tactile_sensor.sensing.array_chain import ArrayChain
from tactile_sensor.sensing.blind import BLIND_MESSAGE
from tactile_sensor.sensing.chain import SignalChain
from tactile_sensor.sensing.rate_calibration import describe_model


class FrameRate:
    """Frames per second between two reports (thread-safe: timer and reader both report)."""

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        self._clock = clock
        self._lock = threading.Lock()
        self._last = (clock(), 0)

    def update(self, frames: int) -> float:
        """The rate since the previous call, given the frame count now [Hz]."""
        now = self._clock()
        with self._lock:
            then, frames_then = self._last
            self._last = (now, frames)
        return max(0, frames - frames_then) / max(now - then, 1e-3)


class LossCounter:
    """ADC frames lost (sequence gaps plus a full backlog) since the previous report."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._reported = 0

    def update(self, stats: ReaderStats) -> tuple[int, str | None]:
        """(frames lost since the last call, the warning to log, or None when none were)."""
        lost = stats.dropped_frames + stats.backlog_dropped
        with self._lock:
            new, self._reported = lost - self._reported, lost
        if new <= 0:
            return 0, None
        return new, (f"{new} ADC frame(s) lost ({stats.dropped_frames} missing in the "
                     f"sequence, {stats.backlog_dropped} dropped with a full backlog, since "
                     "start); the device or the port overflowed: this process gets too "
                     "little CPU")


def _level_message(stats: ReaderStats, adc: AdcSettings | None,
                   chain: SignalChain | ArrayChain, lost_now: int) -> tuple[Level, str]:
    if stats.state is ConnectionState.DISCONNECTED:
        return Level.ERROR, stats.reason
    if stats.state is not ConnectionState.CONNECTED:
        return Level.WARN, stats.reason
    if adc is None:
        message = f"waiting for the device's info frame ({stats.awaiting_info} sample(s) held)"
        if stats.info_errors:
            message += f"; its last was unusable: {stats.last_info_error}"
        return Level.WARN, message
    if not adc.usable:
        return Level.ERROR, adc.problem
    if chain.blind:
        return Level.ERROR, BLIND_MESSAGE
    if not chain.tared:
        return Level.WARN, "not tared yet"
    if chain.calibration is None:
        return Level.WARN, "no calibration yet"
    recalibrate = chain.gain_warning() if isinstance(chain, SignalChain) else None
    if recalibrate is not None:
        return Level.WARN, recalibrate
    if lost_now:
        return Level.WARN, f"streaming; {lost_now} ADC frame(s) lost since the last report"
    return Level.OK, "streaming"


def adc_health(stats: ReaderStats, adc: AdcSettings | None, chain: SignalChain | ArrayChain,
               rate_hz: float, lost_now: int, readings_published: int,
               subscribers: Mapping[str, int] | None = None, wrench_skipped: int = 0
               ) -> Health:
    """``adc``: the settings decided on the device's info frame (None before it came);
    ``rate_hz``: frames per second since the last report; ``lost_now``: frames lost since
    then; ``readings_published``: what left on ~/reading, so a monitor can count losses by
    frame, not by rate; ``subscribers``: matched subscriptions per output (``reading``,
    ``wrench``), so a recorder can be seen to listen before the first frame (a message
    published before the match is not delivered to it); ``wrench_skipped``: readings the
    live ~/wrench left out while the driver worked off a backlog (sensing/live_force.py;
    ~/reading has them)."""
    level, message = _level_message(stats, adc, chain, lost_now)
    usable = adc is not None and adc.usable
    values: dict[str, object] = {
        "connection": stats.state.value, "sample_rate_hz": f"{rate_hz:.1f}",
        "frames": stats.frames, "frames_dropped": stats.dropped_frames,
        "frames_overflowed": stats.backlog_dropped, "frames_backlog": stats.backlog,
        "frames_backlog_peak": stats.backlog_peak,
        "readings_published": readings_published, "wrench_skipped": wrench_skipped,
        "sequence_gaps": stats.sequence_gaps, "crc_errors": stats.crc_errors,
        "frames_over_full_scale": stats.over_full_scale,
        "bytes_discarded": stats.bytes_discarded, "reconnections": stats.connections,
        "calibration_source": chain.calibration_source,
        "calibration_model": describe_model(chain.calibration),
        # the most force the calibration reports: a gripper's force ceiling (docs/gripper.md)
        "full_scale_force_n": "none" if chain.calibration is None
        else f"{chain.calibration.full_scale_force_n:.4g}",
        "baseline_v": "none" if chain.baseline_v is None else f"{chain.baseline_v:.4f}",
        "device": stats.device_info.summary() if stats.device_info else "not stated yet",
        "adc_settings": adc.source.value if adc else "not decided yet",
        "adc_bits": chain.conversion.bits if usable else "none",
        "reference_voltage": f"{chain.conversion.vref_v:g}" if usable else "none",
    }
    values.update({f"{name}_subscribers": n for name, n in (subscribers or {}).items()})
    left_v, left_ratio = chain.headroom()
    values["blind"] = "yes" if chain.blind else "no"
    values["blind_samples"] = chain.blind_samples
    # room left before ambient light saturates the detector (docs/ambient.md); an array's
    # is its most lit module's
    values["detector_headroom_v"] = "none" if left_v != left_v else f"{left_v:.3f}"
    values["detector_headroom_ratio"] = ("none" if left_ratio is None
                                         or left_ratio != left_ratio else f"{left_ratio:.3f}")
    if isinstance(chain, SignalChain):
        # the room's light itself, from the emitter-off sample of a modulated module
        ambient = chain.ambient()
        if ambient is None:
            values["ambient_ratio"] = "not measured (no emitter-off sample: stock module)"
        else:
            values["ambient_v"] = f"{ambient[0]:.3f}"
            values["ambient_ratio"] = "none" if ambient[1] is None else f"{ambient[1]:.3f}"
    values.update(_rest_values(chain))
    if isinstance(chain, ArrayChain):
        baselines = chain.baselines_v or (None,) * len(chain.faces)
        values.update({f"baseline_v.{face}": "none" if b is None else f"{b:.4f}"
                       for face, b in zip(chain.faces, baselines, strict=True)})
        cal = chain.calibration
        if cal is not None:  # the components ~/wrench carries as NaN, and why
            values["unobserved"] = cal.unobserved_reason() or "none"
            values["torque_cutoff_hz"] = f"{chain.torque_cutoff_hz:g}"
    return Health(level, message, {k: str(v) for k, v in values.items()})


def _rest_values(chain: SignalChain | ArrayChain) -> dict[str, object]:
    """What following the module at rest found (sensing/rest_gain.py): how often the
    baseline followed the level at rest, and a module's optical gain against the
    calibration's (an array's is not measured)."""
    config = chain.config
    values: dict[str, object] = {
        "rest_retares": chain.rest_retares if config.rest_retare_time_constant_s > 0
        else "off (rest_retare_time_constant 0)"}
    if isinstance(chain, ArrayChain):
        return values
    gain = chain.optical_gain()
    if gain is None:
        values["optical_gain"] = ("not measured (stock module: its level at rest holds the "
                                  "room's light too)")
        return values
    values["optical_gain"] = "none" if gain[1] is None else f"{gain[0]:.3f}"
    values["optical_gain_reference_drop_v"] = "none" if gain[1] is None else f"{gain[1]:.3f}"
    values["optical_gain_applied"] = "yes" if config.gain_tracking else "no (gain_tracking off)"
    values["optical_gain_bound"] = f"{config.gain_warn_bound:g}"
    return values
