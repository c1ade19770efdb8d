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

The per-module filters, tare windows, baselines and threading are those of every module
layout (``sensing.multi_module``).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

from tactile_sensor.hardware.health import Health, Level
from tactile_sensor.sensing.bend_calibration import (
    JOINT,
    TIP,
    BendCalibration,
    bend_layout_refusal,
)
from tactile_sensor.sensing.chain import ChainConfig, _Parts
from tactile_sensor.sensing.errors import CalibrationError, SensingError
from tactile_sensor.sensing.multi_module import (
    MAX_CHANNEL,
    NAN,
    MultiModuleChain,
)

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


class BendChain(MultiModuleChain[tuple[float, ...], BendReading]):
    """Stateful per-sample processing for the finger's modules; the surface the driver and
    its diagnostics read of ``SignalChain``."""

    CHANNELS_OWNER = "the finger's modules"

    def __init__(self, config: ChainConfig, modules: Sequence[BendModule],
                 calibration: BendCalibration | None = None) -> None:
        self.modules = tuple(BendModule(*m) for m in modules)
        self._start(config, [m.place for m in self.modules],
                    [m.channel for m in self.modules])
        if (refusal := bend_layout_refusal(self.faces)) is not None:
            raise SensingError(refusal)
        self._order: tuple[int, ...] = ()
        self._calibration: BendCalibration | None = None
        self.set_calibration(calibration)
        self.out_of_range = 0  # samples whose angle fell beyond the calibration's range
        self.last: BendReading | None = None

    # -- state others read or set ----------------------------------------------------------

    @property
    def calibration(self) -> BendCalibration | None:
        return self._calibration

    @property
    def rest_retares(self) -> int:
        return 0

    def optical_gain(self) -> None:
        """Not measured: a stock module's level at rest holds the room's light too."""
        return None

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

    # -- per sample ------------------------------------------------------------------------

    def _volts(self, counts: tuple[int, ...]) -> tuple[float, ...]:
        scale = self._volts_per_count
        return tuple([counts[c] * scale for c in self.channels])

    def _step(self, volts: tuple[float, ...], t_us: int, host_ns: int) -> BendReading:
        self._detector_v = min(volts)
        filtered = [f.update(v) for f, v in zip(self._filters, volts)]  # noqa: B905
        for window, v in zip(self._tares, volts):  # noqa: B905
            window.add(v)
        if self._blind.update(self._detector_v):
            self._contact.reset()
            return BendReading(volts[0], NAN, NAN, False, False, t_us, host_ns, NAN, volts,
                               (NAN,) * len(volts), blind=True)
        if self._baselines is None:
            self._auto_tare()
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
