"""The signal chain of a bending finger: its modules on channels of one ADC -> joint angle.

Per sample: counts -> volts -> one filter per module (the single chain's filter and
settings) -> outputs = baselines - filtered -> ``BendCalibration`` -> the joint angle [rad]
and, where two modules separate it from the bend, the fingertip's contact force [N]. An
angle beyond the calibration's range is NaN and counted (``out_of_range``), which the
driver's /diagnostics report as a WARN.

Tare: every module at once, with the finger straight and nothing touching it (the
calibration's zero); refused naming the module not at rest. Until tared and calibrated the
angle is NaN. No re-tare at rest: a finger held bent is steady too, and following it would
move the zero.

Threading as ``SignalChain``: ``process`` and ``process_batch`` in the reader's thread;
``tare``, ``set_calibration`` and the properties from any other; one lock guards the state.
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Sequence
from typing import NamedTuple

from tactile_sensor.hardware.health import Health, Level
from tactile_sensor.sensing.bend_calibration import (
    JOINT,
    TIP,
    BendCalibration,
    bend_layout_refusal,
)
from tactile_sensor.sensing.blind import BLIND_MESSAGE
from tactile_sensor.sensing.chain import ChainConfig, SampleSteps, _Parts
from tactile_sensor.sensing.conversion import AdcConversion
from tactile_sensor.sensing.errors import CalibrationError, SensingError, TareError
from tactile_sensor.sensing.filters import Filter, make_filter
from tactile_sensor.sensing.tare import TareWindow

NAN = float("nan")
MAX_CHANNEL = 7
PLACES = (JOINT, TIP)


class BendModule(NamedTuple):
    channel: int
    place: str  # 'joint' (over the joint) or 'tip' (at the fingertip)


def parse_bend_modules(text: str) -> tuple[BendModule, ...]:
    """``"0:joint,1:tip"`` -> the modules in channel order; ``SensingError`` in one
    sentence per mistake, and for a layout with no module over the joint."""
    modules: list[BendModule] = []
    for entry in (e.strip() for e in text.split(",") if e.strip()):
        channel_text, sep, place = (part.strip() for part in entry.partition(":"))
        if not sep or place not in PLACES:
            raise SensingError(f"Bend module '{entry}' is not CHANNEL:PLACE with PLACE "
                               f"{' or '.join(PLACES)}; write it like '0:joint,1:tip'.")
        try:
            channel = int(channel_text)
        except ValueError:
            channel = -1
        if not 0 <= channel <= MAX_CHANNEL:
            raise SensingError(f"Bend module '{entry}' has channel '{channel_text}'; ADC "
                               f"channels are whole numbers 0..{MAX_CHANNEL}.")
        if any(m.channel == channel or m.place == place for m in modules):
            raise SensingError(f"Bend module '{entry}' repeats a channel or a place; give "
                               "each module its own channel and place.")
        modules.append(BendModule(channel, place))
    if (refusal := bend_layout_refusal([m.place for m in modules])) is not None:
        raise SensingError(refusal)
    return tuple(modules)


class BendReading(NamedTuple):
    """One processed sample. The first seven fields mean what ``Reading``'s do (the joint
    module's voltage and output, the tip force as ``force_n``), so a consumer of single
    readings reads a finger's too; ``saturated`` is an angle beyond the range."""

    voltage_v: float
    output_v: float
    force_n: float  # fingertip contact force; NaN where the layout cannot tell it
    contact: bool
    saturated: bool
    device_time_us: int
    host_time_ns: int
    angle_rad: float  # joint angle; NaN untared, uncalibrated or beyond the range
    voltages_v: tuple[float, ...]  # per module, in modules order, unfiltered
    outputs_v: tuple[float, ...]
    blind: bool = False


class BendTareResult(NamedTuple):
    baselines_v: tuple[float, ...]
    spread_v: float
    samples: int
    places: tuple[str, ...]

    def describe(self) -> str:
        each = ", ".join(f"{p} {b:.4f} V" for p, b in zip(self.places, self.baselines_v,
                                                            strict=True))
        return f"baselines {each} (largest spread {self.spread_v * 1e3:.1f} mV)"


class BendChain(SampleSteps[tuple[float, ...], BendReading]):
    """Stateful per-sample processing for the finger's modules; the surface the driver and
    its diagnostics read of ``SignalChain``."""

    def __init__(self, config: ChainConfig, modules: Sequence[BendModule],
                 calibration: BendCalibration | None = None) -> None:
        self.config = config
        self.config.validate()
        self.modules = tuple(BendModule(*m) for m in modules)
        if (refusal := bend_layout_refusal([m.place for m in self.modules])) is not None:
            raise SensingError(refusal)
        self.faces = tuple(m.place for m in self.modules)
        self.channels = tuple(m.channel for m in self.modules)
        self._lock = threading.Lock()
        parts = _Parts(config)
        self._conversion = parts.adc
        self._volts_per_count = parts.adc.volts_per_count
        self._filters = [self._new_filter() for _ in self.modules]
        self._tares = [self._new_tare() for _ in self.modules]
        self._contact = parts.contact
        self._blind = parts.blind
        self._detector_v = NAN
        self._baselines: tuple[float, ...] | None = None
        self._order: tuple[int, ...] = ()
        self._calibration: BendCalibration | None = None
        self.set_calibration(calibration)
        self._auto_tare_every = max(1, self._tares[0].size // 10)
        self._auto_tare_countdown = 0
        self.out_of_range = 0  # samples whose angle fell beyond the calibration's range
        self.last: BendReading | None = None

    def _new_filter(self) -> Filter:
        c = self.config
        return make_filter(c.filter_name, c.rate_hz, c.filter_params)

    def _new_tare(self) -> TareWindow:
        c = self.config
        return TareWindow(c.rate_hz, c.tare_window_s, c.tare_max_spread_v)

    # -- state others read or set ----------------------------------------------------------

    @property
    def baselines_v(self) -> tuple[float, ...] | None:
        return self._baselines

    @property
    def baseline_v(self) -> float | None:
        return None if self._baselines is None else self._baselines[0]

    @property
    def top_channel(self) -> int:
        return max(self.channels)

    @property
    def tared(self) -> bool:
        return self._baselines is not None

    @property
    def calibration(self) -> BendCalibration | None:
        return self._calibration

    @property
    def calibration_source(self) -> str:
        cal = self._calibration
        return cal.source if cal is not None else "none"

    @property
    def rest_retares(self) -> int:
        return 0

    def optical_gain(self) -> None:
        """Not measured: a stock module's level at rest holds the room's light too."""
        return None

    def _detector_level_v(self) -> float:
        return self._detector_v

    def set_calibration(self, calibration: BendCalibration | None) -> None:
        """Use ``calibration``; ``CalibrationError`` if it reads other modules."""
        order: tuple[int, ...] = ()
        if calibration is not None:
            if sorted(calibration.modules) != sorted(self.faces):
                raise CalibrationError(
                    f"The bend calibration {calibration.source} reads modules "
                    f"{', '.join(calibration.modules)} but the driver's are "
                    f"{', '.join(self.faces)}; fit one for these modules.")
            order = tuple(self.faces.index(m) for m in calibration.modules)
        with self._lock:
            self._calibration, self._order = calibration, order

    def tare(self) -> BendTareResult:
        """Baselines of every module from the last window, all or none."""
        with self._lock:
            if self._blind.blind:
                raise TareError(f"Cannot tare: {BLIND_MESSAGE}.")
            results = []
            for module, window in zip(self.modules, self._tares, strict=True):
                try:
                    results.append(window.evaluate())
                except TareError as exc:
                    raise TareError(f"Module {module.place} (channel {module.channel}): "
                                    f"{exc}") from None
            self._baselines = tuple(r.baseline_v for r in results)
            self._contact.reset()
            return BendTareResult(self._baselines, max(r.spread_v for r in results),
                                  results[0].samples, self.faces)

    @property
    def conversion(self) -> AdcConversion:
        return self._conversion

    def set_conversion(self, conversion: AdcConversion) -> None:
        with self._lock:
            if conversion == self._conversion:
                return
            self._conversion = conversion
            self._volts_per_count = conversion.volts_per_count
            self._forget()

    @property
    def modulation(self) -> None:
        return None

    def set_modulation(self, modulation: object) -> None:
        if modulation is not None:
            raise SensingError("A bending finger's modules are read as stock modules; run "
                               "the ADC without modulation (adc_protocol 2).")

    def reconfigure(self, config: ChainConfig) -> None:
        """Filter, tare and contact settings while samples flow (baselines stay)."""
        self.config = config
        parts = _Parts(config)
        filters = [self._new_filter() for _ in self.modules]
        tares = [self._new_tare() for _ in self.modules]
        with self._lock:
            self._filters, self._tares, self._contact = filters, tares, parts.contact
            self._auto_tare_every = max(1, tares[0].size // 10)

    def reset(self) -> None:
        with self._lock:
            self._forget()
            self._contact.reset()

    def _forget(self) -> None:
        self._blind.reset()
        for f in self._filters:
            f.reset()
        for t in self._tares:
            t.clear()

    # -- per sample ------------------------------------------------------------------------

    def _volts(self, counts: tuple[int, ...]) -> tuple[float, ...]:
        scale = self._volts_per_count
        return tuple([counts[c] * scale for c in self.channels])

    def _missing_channel(self, channels: int) -> SensingError:
        return SensingError(
            f"The sample has {channels} channel(s) but the finger's modules use channel "
            f"{max(self.channels)}; wire fewer modules or raise CHANNELS in the firmware.")

    def _step(self, volts: tuple[float, ...], t_us: int, host_ns: int) -> BendReading:
        self._detector_v = min(volts)
        filtered = [f.update(v) for f, v in zip(self._filters, volts)]  # noqa: B905
        for window, v in zip(self._tares, volts):  # noqa: B905
            window.add(v)
        if self._blind.update(self._detector_v):
            self._contact.reset()
            return BendReading(volts[0], NAN, NAN, False, False, t_us, host_ns, NAN, volts,
                               (NAN,) * len(volts), blind=True)
        if self._baselines is None and self.config.auto_tare and self._tares[0].ready:
            self._auto_tare_countdown -= 1
            if self._auto_tare_countdown <= 0:
                self._auto_tare_countdown = self._auto_tare_every
                with contextlib.suppress(TareError):  # not all at rest yet: retry later
                    self._baselines = tuple(w.evaluate().baseline_v for w in self._tares)
        baselines = self._baselines
        if baselines is None:
            return BendReading(volts[0], NAN, NAN, False, False, t_us, host_ns, NAN, volts,
                               (NAN,) * len(volts))
        outputs = tuple([b - f for b, f in zip(baselines, filtered)])  # noqa: B905
        cal = self._calibration
        if cal is None:
            return BendReading(volts[0], outputs[0], NAN, False, False, t_us, host_ns, NAN,
                               volts, outputs)
        est = cal.estimate([outputs[i] for i in self._order])
        if not est.in_range:
            self.out_of_range += 1
        force = est.tip_force_n
        contact = self._contact.update(force if force == force else 0.0, t_us * 1e-6)
        return BendReading(volts[0], outputs[0], force, contact, not est.in_range, t_us,
                           host_ns, est.angle_rad, volts, outputs)


def bend_health(health: Health, chain: BendChain, reported: int) -> Health:
    """The ADC's health with what the finger's chain adds: a WARN while angles fell beyond
    the calibration's range since the last report (``reported``: the count then), and
    whether the force is observed."""
    cal = chain.calibration
    values = dict(health.values)
    values["bend_modules"] = ", ".join(chain.faces)
    values["angles_out_of_range"] = str(chain.out_of_range)
    values["tip_force"] = ("none" if cal is None else "observed" if cal.separates
                           else f"NaN: {cal.separation}")
    if cal is not None:
        lo, hi = cal.angle_range_rad
        values["angle_range_rad"] = f"{lo:.4f}..{hi:.4f}"
    level, message = health.level, health.message
    beyond = chain.out_of_range - reported
    if beyond > 0 and level == Level.OK:
        level = Level.WARN
        message = (f"{beyond} angle(s) beyond the calibration's range since the last report "
                   "(published as NaN)")
    return Health(level, message, values)
