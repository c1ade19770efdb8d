"""The signal chain: ADC counts → volts → filter → module output → force → contact.

The filter runs on the voltage, and the module output is ``baseline − filtered voltage``
(the paper's inverted output, Sec. III-A). For the linear filters this equals filtering
the output, and it lets the filter run from the first sample on, so a tare never disturbs
its state. Feed every sample to ``process`` (even when publishing fewer): the filter's
behaviour is defined per sample.

A ``RateCalibration`` (static curve plus relaxing rate terms, ``sensing.rate_calibration``)
makes the force depend on the output's history: its terms run on the device's sample
times and start from rest at every tare, baseline change, reset and calibration change.

A modulated device (``set_modulation``) sends each channel's code with the emitter on
and off; the chain's voltage is then the emitter's light alone, as the output a dark room
would give (``sensing.modulation.PairSignal``), and blindness is judged on the detector's
own lower sample.

While it is sure nothing touches the skin the chain follows the level at rest
(``sensing.rest_gain``): the baseline steps toward each quiet window's mean (re-tare at
rest; the rate terms keep running through these small steps), and for a modulated module
the force is read at the optical gain the baseline shows (``Reading.output_v`` stays the
unscaled output).

Threading: ``process`` and ``process_batch`` run in one thread (the reader's); ``tare``,
``set_calibration`` and the properties may be called from another (a service callback). A
lock guards the shared state, taken once per batch.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import threading
from abc import ABC, abstractmethod
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields
from typing import Any, Generic, NamedTuple, Protocol, TypeVar

from tactile_sensor.sensing.blind import BLIND_MESSAGE, SATURATION_V, BlindDetector, headroom
from tactile_sensor.sensing.calibration import Calibration
from tactile_sensor.sensing.contact import ContactDetector
from tactile_sensor.sensing.conversion import AdcConversion
from tactile_sensor.sensing.errors import SensingError, TareError
from tactile_sensor.sensing.filters import DEFAULT_FILTER, make_filter
from tactile_sensor.sensing.modulation import Modulation, PairSignal
from tactile_sensor.sensing.rate_calibration import RateCalibration, RateForceEstimator
from tactile_sensor.sensing.rest_gain import (
    DEFAULT_GAIN_BOUND,
    DEFAULT_RETARE_TIME_CONSTANT_S,
    RestGain,
    RestRetare,
)
from tactile_sensor.sensing.tare import TareResult, TareWindow

NAN = float("nan")


class SampleLike(Protocol):
    """What the chain needs of ``hardware.adc_samples.Sample``."""

    @property
    def device_time_us(self) -> int: ...

    @property
    def host_time_ns(self) -> int: ...

    @property
    def counts(self) -> tuple[int, ...]: ...


class BatchLike(Protocol):
    """What the chain needs of ``hardware.adc_samples.SampleBatch``: consecutive samples as
    columns."""

    @property
    def device_time_us(self) -> Sequence[int]: ...

    @property
    def host_time_ns(self) -> Sequence[int]: ...

    @property
    def counts(self) -> Sequence[tuple[int, ...]]: ...


class _Sourced(Protocol):
    """What the chain needs of any calibration: where it came from."""

    @property
    def source(self) -> str: ...


V = TypeVar("V")
R = TypeVar("R")


class SampleSteps(ABC, Generic[V, R]):
    """A chain's per-sample step, fed a sample or a batch: each sample's volts, then the
    step under the chain's lock, taken once for a whole batch (what one read of the port
    held); the last reading is kept for those who poll."""

    _lock: threading.Lock
    _blind: BlindDetector
    _conversion: AdcConversion
    _volts_per_count: float
    _calibration: _Sourced | None
    last: R | None

    @property
    @abstractmethod
    def baseline_v(self) -> float | None: ...

    @abstractmethod
    def _detector_level_v(self) -> float:
        """The lowest voltage a detector showed in the last sample (NaN: none yet)."""

    @property
    def calibration_source(self) -> str:
        """Where forces come from: 'fem:<digest>', 'file:<path>', ... or 'none'."""
        cal = self._calibration
        return cal.source if cal is not None else "none"

    @property
    def conversion(self) -> AdcConversion:
        return self._conversion

    def set_conversion(self, conversion: AdcConversion) -> None:
        """Use another counts -> volts conversion (the device stated its ADC); a change
        forgets what held volts of the old one (``_conversion_changed``)."""
        with self._lock:
            if conversion == self._conversion:
                return
            self._conversion = conversion
            self._volts_per_count = conversion.volts_per_count
            self._conversion_changed()

    @abstractmethod
    def _conversion_changed(self) -> None:
        """Forget the state whose volts meant something else (call with the lock held)."""

    @property
    def blind(self) -> bool:
        """Whether a detector is at its rail now (force NaN; sensing/blind.py)."""
        return self._blind.blind

    @property
    def blind_samples(self) -> int:
        return self._blind.blind_samples

    def headroom(self) -> tuple[float, float | None]:
        """The detector's room above saturation [V] (an array's: its most lit module's) and
        that as a ratio of the emitter's drop at rest (an array's first module's; None
        before a tare); the supply is taken as the ADC's reference (the module and the ADC
        share VIN on the reference firmware)."""
        volts = SATURATION_V if self._blind.blind else self._detector_level_v()
        return headroom(volts, self.baseline_v, self._conversion.vref_v)

    @abstractmethod
    def _volts(self, counts: tuple[int, ...]) -> V:
        """What the step takes of a sample's codes (IndexError: a channel is missing)."""

    @abstractmethod
    def _step(self, volts: V, t_us: int, host_ns: int) -> R:
        """One sample through the chain (call with the lock held)."""

    @abstractmethod
    def _missing_channel(self, channels: int) -> SensingError: ...

    def process(self, sample: SampleLike) -> R:
        """Run one sample through the chain; ``SensingError`` if it lacks a channel the
        chain reads."""
        try:
            volts = self._volts(sample.counts)
        except IndexError:
            raise self._missing_channel(len(sample.counts)) from None
        with self._lock:
            reading = self._step(volts, sample.device_time_us, sample.host_time_ns)
        self.last = reading
        return reading

    def process_batch(self, batch: BatchLike) -> list[R]:
        """Run a batch of consecutive samples through the chain, one lock for all of them
        (the reader hands over what one read of the port held)."""
        volts_of = self._volts
        try:
            volts = [volts_of(counts) for counts in batch.counts]
        except IndexError:
            raise self._missing_channel(min(map(len, batch.counts))) from None
        step = self._step
        with self._lock:
            readings = [step(v, t_us, host_ns) for v, t_us, host_ns
                        in zip(volts, batch.device_time_us, batch.host_time_ns, strict=True)]
        if readings:
            self.last = readings[-1]
        return readings


class Reading(NamedTuple):
    """One processed sample. ``output_v``/``force_n`` are NaN until the first tare,
    ``force_n`` is NaN while no calibration is set (with a rate-aware calibration it
    includes the rate terms).
    """

    voltage_v: float  # photoreflector voltage after the ADC, unfiltered (modulated: the
    # emitter's light alone as a dark-room output)
    output_v: float  # baseline − filtered voltage
    force_n: float
    contact: bool
    saturated: bool  # output beyond the calibration's last point (force clamped)
    device_time_us: int
    host_time_ns: int
    blind: bool = False  # the detector at its rail (sensing/blind.py): force NaN


@dataclass(frozen=True)
class ChainConfig:
    """Everything the chain needs; ``from_mapping`` validates (e.g. ROS parameters)."""

    rate_hz: float = 1000.0
    adc_bits: int = 12
    vref_v: float = 5.0
    channel: int = 0
    filter_name: str = DEFAULT_FILTER
    filter_params: Mapping[str, float] = field(default_factory=dict)
    tare_window_s: float = 0.5
    tare_max_spread_v: float = 0.05
    auto_tare: bool = True  # tare by itself on the first window found at rest
    contact_on_n: float = 0.5
    contact_off_n: float = 0.3
    contact_debounce_s: float = 0.01
    # at rest the baseline follows the level with this time constant; 0 = off
    rest_retare_time_constant_s: float = DEFAULT_RETARE_TIME_CONSTANT_S
    gain_tracking: bool = True  # modulated: scale the calibration by the gain at rest
    gain_warn_bound: float = DEFAULT_GAIN_BOUND

    @classmethod
    def from_mapping(cls, values: Mapping[str, Any]) -> ChainConfig:
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(values) - known)
        if unknown:
            raise SensingError(f"Unknown signal-chain setting(s) {', '.join(unknown)}; "
                               f"known: {', '.join(sorted(known))}.")
        config = cls(**values)
        config.validate()
        return config

    def validate(self) -> None:
        """Build every part once; each part raises ``SensingError`` naming its parameter."""
        if not isinstance(self.channel, int) or not 0 <= self.channel < 8:
            raise SensingError(f"channel must be 0..7, got {self.channel!r}.")
        for name in ("auto_tare", "gain_tracking"):
            if not isinstance(getattr(self, name), bool):
                raise SensingError(f"{name} must be true or false, got "
                                   f"{getattr(self, name)!r}.")
        _Parts(self)


#: Settings of the ADC side, fixed for a chain's life (``SignalChain.reconfigure``).
FIXED_FIELDS = ("rate_hz", "adc_bits", "vref_v", "channel")


def changed_parts(old: ChainConfig, new: ChainConfig) -> set[str]:
    """Which of 'filter', 'tare', 'contact' and 'rest' a reconfiguration from ``old`` to ``new``
    rebuilds; ``SensingError`` if a ``FIXED_FIELDS`` setting changes or ``new`` is bad."""
    fixed = [name for name in FIXED_FIELDS if getattr(new, name) != getattr(old, name)]
    if fixed:
        raise SensingError(f"{', '.join(fixed)} cannot change while samples flow; build a "
                           "new chain.")
    new.validate()
    keys = {"filter": ("filter_name", "filter_params"),
            "tare": ("tare_window_s", "tare_max_spread_v"),
            "contact": ("contact_on_n", "contact_off_n", "contact_debounce_s"),
            "rest": ("rest_retare_time_constant_s", "gain_tracking", "gain_warn_bound")}
    return {part for part, names in keys.items()
            if any(getattr(new, n) != getattr(old, n) for n in names)}


class _Parts:
    def __init__(self, config: ChainConfig) -> None:
        self.adc = AdcConversion(config.adc_bits, config.vref_v)
        self.filter = make_filter(config.filter_name, config.rate_hz, config.filter_params)
        self.tare = TareWindow(config.rate_hz, config.tare_window_s, config.tare_max_spread_v)
        self.contact = ContactDetector(config.contact_on_n, config.contact_off_n,
                                       config.contact_debounce_s)
        # blind until the filter holds no rail sample: its window, or 10 ms for a recursive one
        window = getattr(self.filter, "window", None)
        self.blind = BlindDetector(window if isinstance(window, int)
                                   else max(1, round(config.rate_hz * 0.01)))
        self.retare = RestRetare(config.rest_retare_time_constant_s, config.rate_hz,
                                 self.tare.size)
        self.gain = RestGain(config.gain_warn_bound)


class SignalChain(SampleSteps["float | tuple[float, float, float]", Reading]):
    """Stateful per-sample processing for one sensor channel."""

    def __init__(self, config: ChainConfig | None = None,
                 calibration: Calibration | RateCalibration | None = None) -> None:
        self.config = config or ChainConfig()
        self.config.validate()
        parts = _Parts(self.config)
        self._conversion = parts.adc
        self._volts_per_count = parts.adc.volts_per_count
        self._filter = parts.filter
        self._tare = parts.tare
        self._contact = parts.contact
        self._blind = parts.blind
        self._retare = parts.retare
        self._gain = parts.gain
        self._output_scale = 1.0  # 1 / the optical gain the calibration is read at
        self._quiet = 0  # samples in a row sure to be at rest (re-tare at rest)
        self._filtered_v = NAN
        self._pair: PairSignal | None = None
        self._detector_v = NAN  # modulated: the lower of the last on and off samples
        self._on_off_v = (NAN, NAN)  # modulated: the last on and off samples
        self._calibration = calibration
        self._static, self._estimator = _force_parts(calibration)
        self._baseline_v: float | None = None
        # A refused auto-tare is retried every tenth of a window, not on every sample.
        self._auto_tare_every = max(1, self._tare.size // 10)
        self._auto_tare_countdown = 0
        self._lock = threading.Lock()
        self.last: Reading | None = None

    # -- state others read or set ----------------------------------------------------------

    @property
    def baseline_v(self) -> float | None:
        return self._baseline_v

    @property
    def tared(self) -> bool:
        return self._baseline_v is not None

    def _detector_level_v(self) -> float:
        """The filtered voltage (stock), or the lower of the last on and off samples."""
        return self._filtered_v if self._pair is None else self._detector_v

    def optical_gain(self) -> tuple[float, float | None] | None:
        """(the optical gain against the calibration's, the emitter's drop at rest it is
        measured against [V], None until known); None for a stock module, whose drop at
        rest holds the room's light too (sensing/rest_gain.py)."""
        if self._pair is None:
            return None
        return self._gain.gain, self._gain.reference_drop_v

    def gain_warning(self) -> str | None:
        """One sentence asking for a recalibration once the optical gain left its bound."""
        return None if self._pair is None else self._gain.warning()

    @property
    def rest_retares(self) -> int:
        """How many steps the baseline took at rest since the re-tare was last configured."""
        return self._retare.retares

    @property
    def top_channel(self) -> int:
        """The highest ADC channel read (the device must send at least one more)."""
        return self.config.channel

    @property
    def calibration(self) -> Calibration | RateCalibration | None:
        return self._calibration

    @property
    def rate_aware(self) -> bool:
        """Whether forces include rate terms (a ``RateCalibration`` is set)."""
        return self._estimator is not None

    def set_calibration(self, calibration: Calibration | RateCalibration | None) -> None:
        with self._lock:
            self._calibration = calibration
            self._static, self._estimator = _force_parts(calibration)
            self._gain.forget()  # the new calibration belongs to the optics as they are
            self._update_gain()

    def tare(self) -> TareResult:
        """Set the baseline from the last ``tare_window_s`` at rest, or raise ``TareError``."""
        with self._lock:
            if self._blind.blind:
                raise TareError(f"Cannot tare: {BLIND_MESSAGE}.")
            result = self._tare.evaluate()
            self._baseline_v = result.baseline_v
            self._contact.reset()
            self._restart_rate_terms()
            self._update_gain()
            return result

    def set_baseline(self, baseline_v: float) -> None:
        """Use a known baseline (e.g. restored after a restart)."""
        if not math.isfinite(baseline_v):
            raise TareError(f"A baseline must be a finite voltage, got {baseline_v!r}.")
        with self._lock:
            self._baseline_v = float(baseline_v)
            self._restart_rate_terms()
            self._update_gain()

    def _conversion_changed(self) -> None:
        """The filter and tare window held volts of the old conversion."""
        if self._pair is not None:
            self._pair = PairSignal(self._pair.modulation, self._conversion.vref_v)
        self._filter.reset()
        self._tare.clear()
        self._restart_rate_terms()
        self._gain.forget()
        self._update_gain()

    def ambient(self) -> tuple[float, float | None] | None:
        """The room's light on the detector as (drop below the supply [V], ratio of the
        emitter's drop at rest; None before a tare), measured from the emitter-off
        sample; None for a device without one (not modulated)."""
        pair = self._pair
        if pair is None:
            return None
        drop = pair.ambient_drop(*self._on_off_v)
        baseline, vref = self._baseline_v, self._conversion.vref_v
        if baseline is None or vref - baseline <= 0 or drop != drop:
            return drop, None
        return drop, drop / (vref - baseline)

    @property
    def modulation(self) -> Modulation | None:
        return None if self._pair is None else self._pair.modulation

    def set_modulation(self, modulation: Modulation | None) -> None:
        """Read on/off pairs as ``modulation`` says for the chain's channel (None: one
        code per channel); a change forgets the filter and tare window, whose volts meant
        something else."""
        if modulation is not None:
            modulation = dataclasses.replace(modulation, channel=self.config.channel)
        with self._lock:
            if modulation == self.modulation:
                return
            self._pair = (None if modulation is None
                          else PairSignal(modulation, self._conversion.vref_v))
            self._filter.reset()
            self._tare.clear()
            self._blind.reset()
            self._restart_rate_terms()
            self._gain.forget()
            self._update_gain()

    def reconfigure(self, config: ChainConfig) -> None:
        """Take new filter, tare, contact and rest settings while samples flow; baseline and
        calibration stay. A part whose settings changed starts afresh (a new filter has no
        history). The ADC settings (``FIXED_FIELDS``) cannot change here."""
        changed = changed_parts(self.config, config)  # validates
        parts = _Parts(config)
        with self._lock:
            if "filter" in changed:
                self._filter = parts.filter
                self._blind.settle_samples = parts.blind.settle_samples
            if "tare" in changed:
                self._tare = parts.tare
                self._auto_tare_every = max(1, self._tare.size // 10)
            if "contact" in changed:
                self._contact = parts.contact
            if changed & {"tare", "rest"}:
                self._retare, self._quiet = parts.retare, 0
                self._gain.bound = parts.gain.bound
            self.config = config
            self._update_gain()

    def reset(self) -> None:
        """Forget filter, tare window, contact state and rate terms' history (after a
        reconnect), keep baseline."""
        with self._lock:
            self._filter.reset()
            self._tare.clear()
            self._contact.reset()
            self._blind.reset()
            self._quiet = 0
            if self._pair is not None:
                self._pair.reset()
            self._restart_rate_terms()

    def _restart_rate_terms(self) -> None:
        """Rate terms start from rest: the outputs they integrated belong to another
        baseline (tare), conversion or connection. Call with the lock held."""
        if self._estimator is not None:
            self._estimator.reset()

    def _update_gain(self) -> None:
        """A modulated module's optical gain from its baseline, and the scale the force is
        read at; 1 for a stock module (call with the lock held)."""
        baseline = self._baseline_v
        if self._pair is None or baseline is None or self._calibration is None:
            self._output_scale = 1.0
            return
        gain = self._gain.observe(self._conversion.vref_v - baseline)
        self._output_scale = 1.0 / gain if self.config.gain_tracking else 1.0

    def _follow_rest(self) -> bool:
        """One step of the baseline toward the level of a window without contact, if it is
        sure to be at rest: steady (the tare's test) and its mean under the contact's
        release force, judged on the mean so that noise does not hide a rest; on a stock
        module a level that fell is taken at once (``RestRetare.follow``). Whether it
        stepped (call with the lock held)."""
        try:
            rest = self._tare.evaluate()
        except TareError:
            return False
        cal = self._calibration
        static = cal.static if isinstance(cal, RateCalibration) else cal
        output = (self._baseline_v - rest.baseline_v) * self._output_scale  # type: ignore[operator]
        if static is None or not static.force(output) < self._contact.off_n:
            return False
        # a stock module's level falls with the room's light: taken at once; a modulated
        # one rejects the room, so its level falls only as its emitter dims, slowly, and
        # the time constant averages its noisier difference into the optical gain
        fell_bound = rest.spread_v if self._pair is None else math.inf
        self._baseline_v = self._retare.follow(self._baseline_v,  # type: ignore[arg-type]
                                               rest.baseline_v, fell_bound)
        self._update_gain()
        return True

    # -- per sample ------------------------------------------------------------------------

    def _volts(self, counts: tuple[int, ...]) -> float | tuple[float, float, float]:
        pair = self._pair
        if pair is None:
            return counts[self.config.channel] * self._volts_per_count
        on = counts[self.config.channel] * self._volts_per_count
        off = counts[pair.off_index] * self._volts_per_count
        return pair.signal(on, off), on, off

    def _missing_channel(self, channels: int) -> SensingError:
        return SensingError(
            f"The sample has {channels} channel(s) but the chain reads channel "
            f"{self.config.channel}; set the channel parameter to match the firmware.")

    def _step(self, volts: float | tuple[float, float, float], t_us: int,
              host_ns: int) -> Reading:
        """One sample's filter, tare window, force and contact (call with the lock held)."""
        if type(volts) is tuple:
            volts, on, off = volts
            self._on_off_v = (on, off)
            self._detector_v = detector_v = on if on < off else off
        else:
            detector_v = volts
        filtered = self._filter.update(volts)
        self._filtered_v = filtered
        tare = self._tare
        tare.add(volts)
        was_blind = self._blind.blind
        if self._blind.update(detector_v):  # type: ignore[arg-type]
            if not was_blind:  # what the contact and rate terms knew is void
                self._contact.reset()
                self._restart_rate_terms()
            self._quiet = 0
            baseline = self._baseline_v
            output = NAN if baseline is None else baseline - filtered
            return Reading(volts, output, NAN, False, False, t_us, host_ns, True)
        if self._baseline_v is None and self.config.auto_tare and tare.ready:
            self._auto_tare_countdown -= 1
            if self._auto_tare_countdown <= 0:
                self._auto_tare_countdown = self._auto_tare_every
                with contextlib.suppress(TareError):  # not at rest yet: retry later
                    self._baseline_v = tare.evaluate().baseline_v
                    self._restart_rate_terms()
                    self._update_gain()
        baseline = self._baseline_v
        if baseline is None:
            return Reading(volts, NAN, NAN, False, False, t_us, host_ns)
        output = baseline - filtered
        scaled = output * self._output_scale
        estimator = self._estimator
        if estimator is not None:
            force, saturated = estimator.update(scaled, t_us * 1e-6)
        elif self._static is not None:
            force, saturated = self._static.evaluate(scaled)
        else:
            force, saturated = NAN, False
        contact = self._contact.update(force, t_us * 1e-6)
        if self._retare.enabled:  # a window without contact may be a rest (_follow_rest)
            if contact or force != force:
                self._quiet = 0
            else:
                self._quiet += 1
                window = self._retare.window_samples
                if self._quiet >= window:
                    # a step waits a whole window for the next; a window not yet at rest
                    # (a light step still in it) is tried again a tenth of a window on
                    self._quiet = 0 if self._follow_rest() else window - self._auto_tare_every
        return Reading(volts, output, force, contact, saturated, t_us, host_ns)


def _force_parts(calibration: Calibration | RateCalibration | None
                 ) -> tuple[Calibration | None, RateForceEstimator | None]:
    """(static curve, None) or (None, a fresh estimator): what ``process`` evaluates."""
    if isinstance(calibration, RateCalibration):
        return None, calibration.estimator()
    return calibration, None
