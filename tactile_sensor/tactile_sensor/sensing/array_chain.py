"""The signal chain of a module array: N modules on N channels of one ADC stream.

Per sample: counts -> volts (one ``AdcConversion`` for the whole device) -> one filter per
module (the single chain's filters and settings) -> outputs = baselines - filtered ->
the wrench (Fx, Fy, Fz, Tx, Ty, Tz) by ``ArrayCalibration`` -> contact on the magnitude
|F|. The parts are the single chain's (``sensing.chain``), one per module; only the fan-out
lives here. The array is blind (sensing/blind.py) while any module's detector is at its
rail: one module blinded by a lamp leaves the wrench unknown, since every component is a
sum over the modules. At rest it follows the level as one module does (re-tare at rest,
sensing/rest_gain.py): a window with no contact, every module steady and the wrench of the
window's mean under the contact's release force moves every baseline. Torque goes through a
low-pass of its own (``Butterworth``, ``torque_cutoff_hz``): it is a small difference of
outputs (docs/array.md: 11.5 mV per module at full twist), so its noise is large next to it,
and that noise grows with the square root of the bandwidth.
A component the calibration does not observe is NaN.

Tare zeroes every module at once (``sensing.multi_module``, which holds the per-module
filters, tare windows, baselines and threading), so the outputs the calibration sees always
share one rest state. Forces are NaN until tared and calibrated.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from tactile_sensor.sensing.array_calibration import FACES, ArrayCalibration, parse_label
from tactile_sensor.sensing.chain import ChainConfig, SignalChain, _Parts, changed_parts
from tactile_sensor.sensing.errors import CalibrationError, SensingError, TareError
from tactile_sensor.sensing.filters import Butterworth
from tactile_sensor.sensing.modulation import Modulation, PairSignal
from tactile_sensor.sensing.multi_module import MAX_CHANNEL, NAN, MultiModuleChain
from tactile_sensor.sensing.rate_calibration import load_file

#: Default torque low-pass cutoff [Hz]: a grasp's torque changes over tenths of a second,
#: and the torque's noise grows with the square root of the bandwidth.
TORQUE_CUTOFF_HZ = 10.0
TORQUE_ORDER = 2


class Module(NamedTuple):
    channel: int
    face: str  # the module's label: a face, or FACE@OFFSET [m] as physics spells it


def module_label(face: str, offset: float) -> str:
    """The canonical label (as ``physics.params.label``): FACE, or FACE@OFFSET."""
    return face if offset == 0 else f"{face}@{offset:.6g}"


def parse_modules(text: str) -> tuple[Module, ...]:
    """``"0:front,1:back,..."`` or ``"0:front@-0.0055,..."`` (offset along the face [m]) ->
    modules in that order, labels canonical; ``""`` -> () (one module on ``channel``, the
    single chain). ``SensingError`` with one sentence per mistake."""
    text = text.strip()
    if not text:
        return ()
    modules: list[Module] = []
    for entry in (e.strip() for e in text.split(",")):
        channel_text, sep, face = (part.strip() for part in entry.partition(":"))
        if not sep or not channel_text or not face:
            raise SensingError(f"Module '{entry}' in modules is not CHANNEL:FACE; write it like "
                               "'0:front,1:back,2:left,3:right'.")
        try:
            channel = int(channel_text)
        except ValueError:
            raise SensingError(f"Module '{entry}' in modules has channel '{channel_text}', "
                               f"which is not a whole number 0..{MAX_CHANNEL}.") from None
        if not 0 <= channel <= MAX_CHANNEL:
            raise SensingError(f"Module '{entry}' in modules has channel {channel}; ADC "
                               f"channels are 0..{MAX_CHANNEL}.")
        try:
            face = module_label(*parse_label(face.replace(" ", "")))
        except ValueError:
            raise SensingError(f"Module '{entry}' in modules has face '{face}'; faces are "
                               f"{', '.join(FACES)}, optionally FACE@OFFSET with the offset "
                               "along the face in m, like front@-0.0055.") from None
        for other in modules:
            if other.channel == channel:
                raise SensingError(f"Channel {channel} appears twice in modules "
                                   f"({other.face} and {face}); give each module its own "
                                   "channel.")
            if other.face == face:
                raise SensingError(f"Module {face} appears twice in modules (channels "
                                   f"{other.channel} and {channel}); a window carries one "
                                   "module (tell a face's windows apart as FACE@OFFSET).")
        modules.append(Module(channel, face))
    if len(modules) < 2:
        raise SensingError(f"modules names one module ({text}); leave modules empty and set "
                           "channel for a single module, or name two or more.")
    return tuple(modules)


class ArrayReading(NamedTuple):
    """One processed sample of the array. The first seven fields mean what ``Reading``'s
    do (the first module's voltage and output, Fz as ``force_n``), so a consumer of single
    readings reads an array's too."""

    voltage_v: float
    output_v: float
    force_n: float  # Fz: pressing positive
    contact: bool  # decided on |F|
    saturated: bool  # some output beyond the calibration's fitted range
    device_time_us: int
    host_time_ns: int
    force_x_n: float
    force_y_n: float
    voltages_v: tuple[float, ...]  # per module, in modules order, unfiltered
    outputs_v: tuple[float, ...]  # per module: baseline - filtered voltage (NaN untared)
    torque_x_nm: float = NAN  # low-passed; NaN where the calibration does not observe it
    torque_y_nm: float = NAN
    torque_z_nm: float = NAN
    blind: bool = False  # a module's detector at its rail (sensing/blind.py): wrench NaN


#: What the array's step takes of one sample: every module's volts, in ``modules`` order,
#: and the lowest voltage any module's detector shows (the on or off sample of a modulated
#: module, whichever has more light).
ArrayVolts = tuple[tuple[float, ...], float]


class ArrayChain(MultiModuleChain[ArrayVolts, ArrayReading]):
    """Stateful per-sample processing for several modules; the surface of ``SignalChain``."""

    def __init__(self, config: ChainConfig, modules: Sequence[Module],
                 calibration: ArrayCalibration | None = None,
                 torque_cutoff_hz: float = TORQUE_CUTOFF_HZ) -> None:
        if len(modules) < 2:
            raise SensingError("An array chain needs two or more modules; use SignalChain "
                               "for one.")
        self.modules = tuple(Module(*m) for m in modules)
        parts = self._start(config, [m.face for m in self.modules],
                            [m.channel for m in self.modules])
        self._pairs: list[PairSignal] | None = None  # a modulated device: one per module
        self._retare = parts.retare
        self._quiet = 0  # samples in a row sure to be at rest (re-tare at rest)
        self.torque_cutoff_hz = float(torque_cutoff_hz)
        self._torque_filters = [self._new_torque_filter() for _ in range(3)]
        self._torque_seen = (False, False, False)
        # the force's slow part (tilt, twist), low-passed like the torques
        self._slow_filters = [self._new_torque_filter() for _ in range(3)]
        self._slow = False
        self._calibration: ArrayCalibration | None = None
        self.set_calibration(calibration)
        self.last: ArrayReading | None = None

    def _new_torque_filter(self) -> Butterworth:
        try:
            return Butterworth(self.config.rate_hz, TORQUE_ORDER, self.torque_cutoff_hz)
        except (SensingError, ValueError) as exc:
            raise SensingError(f"torque_cutoff_hz = {self.torque_cutoff_hz:g} Hz does not fit "
                               f"the {self.config.rate_hz:g} Hz sample rate ({exc}); set it "
                               "below half the sample rate.") from None

    # -- state others read or set ----------------------------------------------------------

    @property
    def calibration(self) -> ArrayCalibration | None:
        return self._calibration

    def set_calibration(self, calibration: ArrayCalibration | None) -> None:
        """Use ``calibration`` (its modules put in the channels' order); ``CalibrationError``
        if its modules are not the driver's."""
        if calibration is not None:
            try:
                calibration = calibration.reordered(self.faces)
            except CalibrationError:
                raise CalibrationError(
                    f"The array calibration {calibration.source} is for modules "
                    f"{', '.join(calibration.faces)} but the driver's modules are "
                    f"{', '.join(self.faces)}; fit one for these modules or set modules to "
                    "match.") from None
        seen = (False,) * 3 if calibration is None else tuple(
            c in calibration.observed for c in ("tx", "ty", "tz"))
        with self._lock:
            self._calibration = calibration
            self._torque_seen = seen
            self._slow = calibration is not None and calibration.has_slow
            self._reset_torque()

    def _reset_torque(self) -> None:
        for f in (*self._torque_filters, *self._slow_filters):
            f.reset()

    def _baselines_set(self) -> None:
        """New baselines: the low-passes and the count toward a rest start over."""
        self._quiet = 0
        self._reset_torque()

    def _conversion_changed(self) -> None:
        """Filters, tare windows and the modules' on/off pairs held the old volts."""
        if self._pairs is not None:
            self._pairs = self._new_pairs(self._pairs[0].modulation)
        self._forget()

    @property
    def modulation(self) -> Modulation | None:
        """How a modulated device samples the first module (None: not modulated)."""
        return None if self._pairs is None else self._pairs[0].modulation

    def set_modulation(self, modulation: Modulation | None) -> None:
        """As ``SignalChain.set_modulation``, for every module's channel: each module's
        voltage is its emitter's light alone."""
        with self._lock:
            pairs = None if modulation is None else self._new_pairs(modulation)
            if (None if pairs is None else pairs[0].modulation) == self.modulation:
                return
            self._pairs = pairs
            self._forget()

    def _new_pairs(self, modulation: Modulation) -> list[PairSignal]:
        return [PairSignal(dataclasses.replace(modulation, channel=c), self._conversion.vref_v)
                for c in self.channels]

    def reconfigure(self, config: ChainConfig) -> None:
        """As ``SignalChain.reconfigure``: filter, tare and contact settings while samples
        flow (baselines and calibration stay); a changed part restarts in every module."""
        changed = changed_parts(self.config, config)
        self.config = config
        filters = [self._new_filter() for _ in self.modules] if "filter" in changed else None
        tares = [self._new_tare() for _ in self.modules] if "tare" in changed else None
        parts = _Parts(config)
        with self._lock:
            if filters is not None:
                self._filters = filters
                self._blind.settle_samples = parts.blind.settle_samples
            if tares is not None:
                self._tares = tares
                self._auto_tare_every = max(1, tares[0].size // 10)
            if "contact" in changed:
                self._contact = parts.contact
            if changed & {"tare", "rest"}:
                self._retare, self._quiet = parts.retare, 0

    @property
    def rest_retares(self) -> int:
        """How many steps the baselines took at rest since the re-tare was last configured."""
        return self._retare.retares

    def _forget(self) -> None:
        super()._forget()
        self._quiet = 0
        for pair in self._pairs or ():
            pair.reset()
        self._reset_torque()

    # -- per sample ------------------------------------------------------------------------

    def _volts(self, counts: tuple[int, ...]) -> ArrayVolts:
        scale = self._volts_per_count
        if self._pairs is not None:  # a modulated device: each module's emitter light
            on = [counts[c] * scale for c in self.channels]
            off = [counts[p.off_index] * scale for p in self._pairs]
            return (tuple([p.signal(a, b) for p, a, b in zip(self._pairs, on, off)]),  # noqa: B905
                    min(min(on), min(off)))
        volts = tuple([counts[c] * scale for c in self.channels])
        return volts, min(volts)

    def _step(self, sample: ArrayVolts, t_us: int, host_ns: int) -> ArrayReading:
        """One sample of every module (call with the lock held)."""
        volts, self._detector_v = sample
        filtered = [f.update(v) for f, v in zip(self._filters, volts)]  # noqa: B905
        for window, v in zip(self._tares, volts):  # noqa: B905 - one per module
            window.add(v)
        was_blind = self._blind.blind
        if self._blind.update(self._detector_v):
            if not was_blind:  # what the contact and the low-passes knew is void
                self._contact.reset()
                self._reset_torque()
            self._quiet = 0
            baselines = self._baselines
            outputs = (NAN,) * len(volts) if baselines is None else tuple(
                [b - f for b, f in zip(baselines, filtered)])  # noqa: B905
            return ArrayReading(volts[0], outputs[0], NAN, False, False, t_us, host_ns, NAN,
                                NAN, volts, outputs, blind=True)
        if self._baselines is None:
            self._auto_tare()
        baselines = self._baselines
        if baselines is None:
            return ArrayReading(volts[0], NAN, NAN, False, False, t_us, host_ns, NAN, NAN,
                                volts, (NAN,) * len(volts))
        outputs = tuple([b - f for b, f in zip(baselines, filtered)])  # noqa: B905
        cal = self._calibration
        if cal is None:
            fx = fy = fz = tx = ty = tz = NAN
            saturated = False
        else:
            if self._slow:
                fx, fy, fz, tx, ty, tz, sx, sy, sz = cal.wrench_parts_unchecked(outputs)
                slow = self._slow_filters
                fx += slow[0].update(sx)
                fy += slow[1].update(sy)
                fz += slow[2].update(sz)
            else:
                fx, fy, fz, tx, ty, tz = cal.wrench_unchecked(outputs)
            saturated = not cal.in_range(outputs)
            seen = self._torque_seen
            if seen[0]:
                tx = self._torque_filters[0].update(tx)
            if seen[1]:
                ty = self._torque_filters[1].update(ty)
            if seen[2]:
                tz = self._torque_filters[2].update(tz)
        square = fz * fz if fz == fz else 0.0   # an unobserved axis adds nothing to |F|
        if fx == fx:
            square += fx * fx
        if fy == fy:
            square += fy * fy
        contact = self._contact.update(math.sqrt(square), t_us * 1e-6)
        if self._retare.enabled:  # a window without contact may be a rest (_follow_rest)
            if contact or cal is None:
                self._quiet = 0
            else:
                self._quiet += 1
                if self._quiet >= self._retare.window_samples:
                    self._quiet = 0
                    self._follow_rest(baselines, cal)
        return ArrayReading(volts[0], outputs[0], fz, contact, saturated, t_us, host_ns, fx,
                            fy, volts, outputs, tx, ty, tz)


    def _follow_rest(self, baselines: tuple[float, ...], cal: ArrayCalibration) -> None:
        """One step of every baseline toward its module's level over a window without
        contact, if the array is sure to be at rest: every module steady (the tare's test)
        and the force of the window's mean outputs under the contact's release force
        (call with the lock held)."""
        try:
            rest = np.array([w.evaluate().baseline_v for w in self._tares])
        except TareError:
            return
        parts = cal.wrench_unchecked(np.asarray(baselines) - rest)[:3]
        if not math.sqrt(sum(f * f for f in parts if f == f)) < self._contact.off_n:
            return
        self._baselines = tuple(float(b) for b in self._retare.follow(np.asarray(baselines),
                                                                     rest))


def build_chain(config: ChainConfig, modules: Sequence[Module],
                calibration_file: str | None = None,
                torque_cutoff_hz: float = TORQUE_CUTOFF_HZ) -> SignalChain | ArrayChain:
    """The chain for ``modules`` (() = one module on ``config.channel``), calibrated from
    ``calibration_file`` (a curve for one module, with rate terms when the file has them;
    an array calibration for several) or waiting for one (None)."""
    if modules:
        array_cal = None if calibration_file is None else ArrayCalibration.from_file(
            calibration_file)
        return ArrayChain(config, modules, array_cal, torque_cutoff_hz)
    cal = None if calibration_file is None else load_file(calibration_file)
    return SignalChain(config, cal)
