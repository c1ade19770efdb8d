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
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tactile_sensor.sensing.calibration import (
    FILE_FORMAT,
    FILE_VERSION,
    Calibration,
    check_version,
    file_source,
    read_json_file,
)
from tactile_sensor.sensing.errors import CalibrationError
from tactile_sensor.sensing.prony import PronySeries

MAX_RATE_TERMS = 3
NAN = float("nan")


@dataclass(frozen=True)
class RateTerm:
    """One relaxing term: relative modulus ``g`` [1] and relaxation time ``tau_s`` [s]."""

    g: float
    tau_s: float


class RateCalibration:
    """A static ``Calibration`` and 1–3 ``RateTerm``s; ``estimator()`` runs it per sample."""

    def __init__(self, static: Calibration, terms: Sequence[RateTerm]) -> None:
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

    @property
    def source(self) -> str:
        return self.static.source

    @source.setter
    def source(self, value: str) -> None:
        self.static.source = value

    @property
    def g(self) -> tuple[float, ...]:
        return tuple(t.g for t in self.terms)

    @property
    def tau_s(self) -> tuple[float, ...]:
        return tuple(t.tau_s for t in self.terms)

    @property
    def instant_gain(self) -> float:
        """F / F_s for a step change (all terms active): 1 + sum g_i."""
        return 1.0 + sum(self.g)

    def estimator(self) -> RateForceEstimator:
        return RateForceEstimator(self)

    # -- file --------------------------------------------------------------------------------

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any], source: str) -> RateCalibration:
        """From a version-2 mapping whose ``rate_terms`` is a non-empty list."""
        terms_data = data.get("rate_terms") if isinstance(data, Mapping) else None
        if not isinstance(terms_data, list) or not terms_data:
            raise CalibrationError(f"{source}: has no rate_terms list; load it as a static "
                                   "calibration or refit it with several speeds.")
        if check_version(data, source) < 2:
            raise CalibrationError(f"{source}: a version-1 calibration file cannot hold "
                                   "rate_terms; write it as version 2 or refit it.")
        static = Calibration.from_mapping({**data, "rate_terms": []}, source)
        terms = []
        for k, item in enumerate(terms_data):
            try:
                terms.append(RateTerm(float(item["g"]), float(item["tau_s"])))
            except (TypeError, KeyError, ValueError):
                raise CalibrationError(f"{source}: rate_terms[{k}] must be an object with "
                                       "numbers 'g' and 'tau_s'; refit it.") from None
        return cls(static, terms)

    def to_dict(self, fit: Mapping[str, Any] | None = None) -> dict[str, Any]:
        out = self.static.to_dict(fit)
        out["format"], out["version"] = FILE_FORMAT, FILE_VERSION
        out["rate_terms"] = [{"g": t.g, "tau_s": t.tau_s} for t in self.terms]
        return out

    def to_file(self, path: Path | str, fit: Mapping[str, Any] | None = None) -> None:
        Path(path).write_text(json.dumps(self.to_dict(fit), indent=1) + "\n", encoding="utf-8")

    def __repr__(self) -> str:
        return f"RateCalibration({self.static!r}, {self.describe()})"

    def describe(self) -> str:
        """The model in one phrase, for logs and diagnostics."""
        terms = ", ".join(f"g={t.g:.4g} tau={t.tau_s:.4g} s" for t in self.terms)
        return f"rate-aware ({len(self.terms)} term(s): {terms})"


def describe_model(calibration: object) -> str:
    """Which force model a chain runs: 'rate-aware (...)', 'static' or 'none'."""
    if isinstance(calibration, RateCalibration):
        return calibration.describe()
    return "none" if calibration is None else "static"


class RateForceEstimator:
    """One chain's running estimate. ``update(output_v, time_s)`` per sample; a NaN output
    or a time that goes back (a device reboot) restarts the terms from rest."""

    __slots__ = ("_evaluate", "_last_time_s", "_series", "calibration")

    def __init__(self, calibration: RateCalibration) -> None:
        self.calibration = calibration
        self._evaluate = calibration.static.evaluate
        self._series = PronySeries(calibration.g, calibration.tau_s)
        self._last_time_s: float | None = None

    def reset(self) -> None:
        self._series.reset()
        self._last_time_s = None

    def update(self, output_v: float, time_s: float) -> tuple[float, bool]:
        """(force [N], saturated) for this sample, exact for a piecewise-linear F_s."""
        static_n, saturated = self._evaluate(output_v)
        if static_n != static_n:  # NaN: no force, and the terms restart when it returns
            self.reset()
            return NAN, saturated
        last = self._last_time_s
        self._last_time_s = time_s
        if last is None or time_s < last:
            self._series.reset()
            dt = 0.0
        else:
            dt = time_s - last
        return static_n + self._series.step(static_n, dt), saturated


def load_file(path: Path | str) -> Calibration | RateCalibration:
    """A calibration file as the driver should use it: a ``RateCalibration`` when the file
    holds rate terms (version 2), else the static ``Calibration`` (version 1 or 2)."""
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
