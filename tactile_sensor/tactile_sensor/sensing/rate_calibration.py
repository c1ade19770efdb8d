"""Output → force across indentation speeds: a static curve plus relaxing rate terms.

The module reads deformation, which follows the indentation quasi-statically, but the
silicone's force rises with speed (6.70 / 6.81 / 7.01 N at 0.1 / 1 / 10 mm/s for the same
~0.50 V in the mock's ``speeds`` protocol) and relaxes during a hold. A quasi-linear
viscoelastic (Fung) estimator reproduces that from the output alone:

    F_s(t) = C(output(t))                       the static (relaxed) curve
    F(t)   = F_s(t) + sum_i h_i(t),   dh_i/dt = g_i dF_s/dt − h_i / tau_i

with 1–3 terms (g_i ≥ 0 relative moduli, tau_i > 0 s), the same recursion as physics'
``RateDependentForce`` (``sensing.prony``), so it is exact for a piecewise-linear F_s.
``RateCalibration`` is the immutable description (file format version 2,
docs/CONTRACTS.md); a ``RateForceEstimator`` holds one chain's state, which a tare resets
(the h_i belong to the old baseline's outputs).

Play (file version 3): the module's output trails the probe by a fixed indentation on
loading and follows it at once on unloading (the paper's lag x speed is nearly constant),
so at one output the relaxed force differs by direction, also in a hold, and no rate term
follows that. With a ``Play`` the static curve has two branches, C ± half_gap(output),
and a ``DirectionTracker`` picks one: loading (+) until the output, smoothed, has fallen
by ``band_v`` below its highest value since, then unloading (−) until it has risen by
``band_v`` above its lowest. The band keeps the output's noise from flipping it; the cost
is a late switch (band / output speed plus the smoothing's lag) after each reversal. The
rate terms stay driven by the branch's force. All half-gaps 0 is today's model exactly.
"""

from __future__ import annotations

import itertools
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tactile_sensor.sensing.calibration import (
    FILE_FORMAT,
    FILE_VERSION,
    RATE_FILE_VERSION,
    Calibration,
    check_version,
    file_source,
    read_json_file,
)
from tactile_sensor.sensing.errors import CalibrationError
from tactile_sensor.sensing.prony import PronySeries

MAX_RATE_TERMS = 3
ROUNDING_N = 1e-9  # relative dip a branch may show from rounding (curve ± half-gap)
NAN = float("nan")


@dataclass(frozen=True)
class RateTerm:
    """One relaxing term: relative modulus ``g`` [1] and relaxation time ``tau_s`` [s]."""

    g: float
    tau_s: float


@dataclass(frozen=True)
class Play:
    """The static curve's direction split: ``half_gap_n`` [N] per curve point (loading
    branch = curve + half_gap, unloading = curve − half_gap), and the direction tracker's
    ``band_v`` [V] and first-order ``smoothing_hz`` [Hz]."""

    half_gap_n: tuple[float, ...]
    band_v: float
    smoothing_hz: float

    @property
    def max_half_gap_n(self) -> float:
        return max(abs(v) for v in self.half_gap_n)

    def to_dict(self) -> dict[str, Any]:
        return {"half_gap_n": list(self.half_gap_n), "band_v": self.band_v,
                "smoothing_hz": self.smoothing_hz}


class DirectionTracker:
    """Loading or unloading from the output alone, with a hysteresis ``band_v`` [V] on the
    output smoothed by a first-order low-pass at ``smoothing_hz`` (module docstring).
    Starts loading (a press begins by loading; at rest the branches nearly meet)."""

    __slots__ = ("_alpha", "_band", "_dt", "_extreme", "_omega", "_smooth", "rising")

    def __init__(self, band_v: float, smoothing_hz: float) -> None:
        self._band = float(band_v)
        self._omega = 2.0 * math.pi * float(smoothing_hz)
        self._dt = -1.0
        self._alpha = 1.0
        self.reset()

    def reset(self) -> None:
        self._smooth: float | None = None
        self._extreme = 0.0
        self.rising = True

    def update(self, output_v: float, dt_s: float) -> bool:
        """Advance by ``dt_s`` [s] to ``output_v``; True while loading."""
        smooth = self._smooth
        if smooth is None:
            self._smooth = self._extreme = output_v
            return self.rising
        if dt_s != self._dt:
            self._dt = dt_s
            self._alpha = -math.expm1(-self._omega * dt_s)
        smooth += self._alpha * (output_v - smooth)
        self._smooth = smooth
        if self.rising:
            if smooth > self._extreme:
                self._extreme = smooth
            elif smooth < self._extreme - self._band:
                self.rising = False
                self._extreme = smooth
        elif smooth < self._extreme:
            self._extreme = smooth
        elif smooth > self._extreme + self._band:
            self.rising = True
            self._extreme = smooth
        return self.rising


class RateCalibration:
    """A static ``Calibration``, 1–3 ``RateTerm``s and optionally a ``Play``;
    ``estimator()`` runs it per sample."""

    def __init__(self, static: Calibration, terms: Sequence[RateTerm],
                 play: Play | None = None) -> None:
        where = static.source or "the calibration"
        terms = tuple(terms)
        if not 1 <= len(terms) <= MAX_RATE_TERMS:
            raise CalibrationError(f"{where}: a rate-aware calibration needs 1 to "
                                   f"{MAX_RATE_TERMS} rate terms, got {len(terms)}; refit it.")
        for k, term in enumerate(terms):
            if not (math.isfinite(term.g) and term.g >= 0.0):
                raise CalibrationError(f"{where}: rate term {k} has modulus g={term.g!r}; "
                                       "g must be a finite number >= 0, refit it.")
            if not (math.isfinite(term.tau_s) and term.tau_s > 0.0):
                raise CalibrationError(f"{where}: rate term {k} has tau_s={term.tau_s!r}; a "
                                       "relaxation time must be finite and > 0 s, refit it.")
        self.static = static
        self.terms = terms
        self.play = play
        self.branches = (static, static) if play is None else _branches(static, play, where)

    @property
    def source(self) -> str:
        return self.static.source

    @source.setter
    def source(self, value: str) -> None:
        for curve in (self.static, *self.branches):
            curve.source = value

    @property
    def g(self) -> tuple[float, ...]:
        return tuple(t.g for t in self.terms)

    @property
    def tau_s(self) -> tuple[float, ...]:
        return tuple(t.tau_s for t in self.terms)

    @property
    def full_scale_force_n(self) -> float:
        """The static curve's last force [N]: the relaxed force it saturates at (the rate
        terms add to it only while the load changes)."""
        return self.static.full_scale_force_n

    @property
    def instant_gain(self) -> float:
        """F / F_s for a step change (all terms active): 1 + sum g_i."""
        return 1.0 + sum(self.g)

    def estimator(self) -> RateForceEstimator:
        return RateForceEstimator(self)

    # -- file --------------------------------------------------------------------------------

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any], source: str) -> RateCalibration:
        """From a version-2 or -3 mapping whose ``rate_terms`` is a non-empty list (and, in
        version 3, optionally ``play``)."""
        terms_data = data.get("rate_terms") if isinstance(data, Mapping) else None
        if not isinstance(terms_data, list) or not terms_data:
            raise CalibrationError(f"{source}: has no rate_terms list; load it as a static "
                                   "calibration or refit it with several speeds.")
        version = check_version(data, source)
        if version < 2:
            raise CalibrationError(f"{source}: a version-1 calibration file cannot hold "
                                   "rate_terms; write it as version 2 or refit it.")
        play_data = data.get("play")
        if play_data is not None and version < 3:
            raise CalibrationError(f"{source}: a version-{version} calibration file cannot "
                                   "hold play (an older reader would ignore it); write it as "
                                   "version 3 or refit it.")
        static = Calibration.from_mapping({**data, "rate_terms": [], "play": None}, source)
        terms = []
        for k, item in enumerate(terms_data):
            try:
                terms.append(RateTerm(float(item["g"]), float(item["tau_s"])))
            except (TypeError, KeyError, ValueError):
                raise CalibrationError(f"{source}: rate_terms[{k}] must be an object with "
                                       "numbers 'g' and 'tau_s'; refit it.") from None
        return cls(static, terms, None if play_data is None else _play_from(play_data, source))

    def to_dict(self, fit: Mapping[str, Any] | None = None) -> dict[str, Any]:
        out = self.static.to_dict(fit)
        # without play, version 2: readers from before play take it unchanged; with play,
        # version 3, which they refuse (their static curve alone would be off by half_gap)
        out["format"] = FILE_FORMAT
        out["version"] = RATE_FILE_VERSION if self.play is None else FILE_VERSION
        out["rate_terms"] = [{"g": t.g, "tau_s": t.tau_s} for t in self.terms]
        if self.play is not None:
            out["play"] = self.play.to_dict()
        return out

    def to_file(self, path: Path | str, fit: Mapping[str, Any] | None = None) -> None:
        Path(path).write_text(json.dumps(self.to_dict(fit), indent=1) + "\n", encoding="utf-8")

    def __repr__(self) -> str:
        return f"RateCalibration({self.static!r}, {self.describe()})"

    def describe(self) -> str:
        """The model in one phrase, for logs and diagnostics."""
        terms = ", ".join(f"g={t.g:.4g} tau={t.tau_s:.4g} s" for t in self.terms)
        play = self.play
        if play is None:
            return f"rate-aware ({len(self.terms)} term(s): {terms})"
        return (f"rate-aware ({len(self.terms)} term(s): {terms}; play: half-gap up to "
                f"{play.max_half_gap_n:.3g} N, band {1e3 * play.band_v:.3g} mV)")


def describe_model(calibration: object) -> str:
    """Which force model a chain runs: 'rate-aware (...)', 'static' or 'none'."""
    if isinstance(calibration, RateCalibration):
        return calibration.describe()
    return "none" if calibration is None else "static"


class RateForceEstimator:
    """One chain's running estimate. ``update(output_v, time_s)`` per sample; a NaN output
    or a time that goes back (a device reboot) restarts the terms (and the direction) from
    rest. O(1) per sample: one curve lookup, one tracker step, 1–3 term steps."""

    __slots__ = ("_evaluate", "_last_time_s", "_series", "_tracker", "_unloading",
                 "calibration")

    def __init__(self, calibration: RateCalibration) -> None:
        self.calibration = calibration
        loading, unloading = calibration.branches
        self._evaluate = loading.evaluate
        self._unloading = unloading.evaluate
        play = calibration.play
        self._tracker = (None if play is None
                         else DirectionTracker(play.band_v, play.smoothing_hz))
        self._series = PronySeries(calibration.g, calibration.tau_s)
        self._last_time_s: float | None = None

    @property
    def loading(self) -> bool:
        """The branch in use (always True without play)."""
        return self._tracker is None or self._tracker.rising

    def reset(self) -> None:
        self._series.reset()
        if self._tracker is not None:
            self._tracker.reset()
        self._last_time_s = None

    def update(self, output_v: float, time_s: float) -> tuple[float, bool]:
        """(force [N], saturated) for this sample, exact for a piecewise-linear F_s."""
        if output_v != output_v:  # NaN: no force, and the terms restart when it returns
            self.reset()
            return NAN, False
        last = self._last_time_s
        self._last_time_s = time_s
        if last is None or time_s < last:
            self._series.reset()
            if self._tracker is not None:
                self._tracker.reset()
            dt = 0.0
        else:
            dt = time_s - last
        tracker = self._tracker
        if tracker is None or tracker.update(output_v, dt):
            static_n, saturated = self._evaluate(output_v)
        else:
            static_n, saturated = self._unloading(output_v)
        return static_n + self._series.step(static_n, dt), saturated


def _branches(static: Calibration, play: Play, where: str) -> tuple[Calibration, Calibration]:
    """(loading, unloading) curves of ``static`` split by ``play``; CalibrationError when
    they do not fit together (one sentence)."""
    if len(play.half_gap_n) != len(static.output_v):
        raise CalibrationError(f"{where}: play has {len(play.half_gap_n)} half-gaps but the "
                               f"curve has {len(static.output_v)} points; refit it.")
    if not all(math.isfinite(v) for v in play.half_gap_n):
        raise CalibrationError(f"{where}: play's half_gap_n contains NaN or infinite values; "
                               "refit it.")
    for name, value in (("band_v", play.band_v), ("smoothing_hz", play.smoothing_hz)):
        if not (math.isfinite(value) and value > 0.0):
            raise CalibrationError(f"{where}: play's {name} is {value!r}; it must be finite "
                                   "and > 0, refit it.")
    mid = static.force_n
    branches = []
    for sign in (1.0, -1.0):
        force = [f + sign * h for f, h in zip(mid, play.half_gap_n, strict=True)]
        # curve ± half-gap of two non-decreasing branches may dip by a rounding error
        if any(b < a - ROUNDING_N * (1.0 + abs(a)) for a, b in itertools.pairwise(force)):
            raise CalibrationError(f"{where}: play's half-gaps make a branch's force "
                                   "decrease; refit it.")
        branches.append(Calibration(static.output_v, list(itertools.accumulate(force, max)),
                                    static.source))
    return branches[0], branches[1]


def _play_from(data: Any, source: str) -> Play:
    """A ``Play`` from a file's ``play`` object, or one sentence naming what is wrong."""
    try:
        return Play(tuple(float(v) for v in data["half_gap_n"]), float(data["band_v"]),
                    float(data["smoothing_hz"]))
    except (TypeError, KeyError, ValueError):
        raise CalibrationError(f"{source}: play must be an object with a list 'half_gap_n' "
                               "and numbers 'band_v' and 'smoothing_hz'; refit it.") from None


def load_file(path: Path | str) -> Calibration | RateCalibration:
    """A calibration file as the driver should use it: a ``RateCalibration`` when the file
    holds rate terms (version 2, or 3 with play), else the static ``Calibration``."""
    path = Path(path)
    data = read_json_file(path, "Calibration file", "run the analysis to write one",
                          "rewrite it with the analysis tools")
    where = f"file:{path}"
    if isinstance(data, Mapping) and data.get("format") == FILE_FORMAT:
        check_version(data, where)
        if data.get("rate_terms"):
            cal = RateCalibration.from_mapping(data, where)
            cal.source = file_source(path, data)
            return cal
    return Calibration.from_file(path)
