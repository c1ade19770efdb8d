"""Per-excursion gain and error of each wrench component: metrics that cannot hide a bias.

An RMSE over a whole run divides by the range of the component's largest excursion, so an
estimate that reads half of a smaller excursion (a tilt's torque beside a shear's) can pass
it. Here each excursion is judged on its own: an excursion is a stretch where the gauge's
|value| exceeds ``EXCURSION_FRACTION`` of that component's largest |value| in the
recording; its gain is the least-squares gain of the estimate on the gauge through the
origin (sum(e r) / sum(r r): 1 reads the load right, 0.5 half of it), its RMSE the error's
over the stretch.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: An excursion: where |gauge| exceeds this share of the component's largest |gauge|.
EXCURSION_FRACTION = 0.25
#: At rest: where every component's |gauge| is at most this share of its largest.
REST_FRACTION = 0.01


@dataclass(frozen=True)
class Excursion:
    """One stretch [start, stop) of samples, its gain and RMSE (the component's unit)."""

    start: int
    stop: int
    gain: float
    rmse: float


def stretches(mask: np.ndarray) -> list[tuple[int, int]]:
    """(start, stop) of every run of True in ``mask``, stop exclusive."""
    edges = np.diff(np.concatenate(([0], np.asarray(mask, bool).astype(np.int8), [0])))
    return list(zip(np.flatnonzero(edges == 1).tolist(), np.flatnonzero(edges == -1).tolist(),
                    strict=True))


def excursions(estimate: np.ndarray, reference: np.ndarray,
               fraction: float = EXCURSION_FRACTION) -> list[Excursion]:
    """The excursions of one component (1-D, one grid): empty when the gauge never leaves
    zero; a gain of NaN where the estimate is NaN (a component the driver does not publish)."""
    estimate, reference = np.asarray(estimate, float), np.asarray(reference, float)
    finite = np.isfinite(reference)
    top = float(np.max(np.abs(reference[finite]))) if finite.any() else 0.0
    if top <= 0.0:
        return []
    found = []
    for start, stop in stretches(finite & (np.abs(np.where(finite, reference, 0.0))
                                           > fraction * top)):
        r, e = reference[start:stop], estimate[start:stop]
        if np.all(np.isfinite(e)):
            gain = float(np.dot(e, r) / np.dot(r, r))
            rmse = float(np.sqrt(np.mean((e - r) ** 2)))
        else:
            gain = rmse = float("nan")
        found.append(Excursion(start, stop, gain, rmse))
    return found


def worst_gain(gains: list[float]) -> float | None:
    """The gain farthest from 1 (None without a finite one)."""
    finite = [g for g in gains if np.isfinite(g)]
    return max(finite, key=lambda g: abs(g - 1.0)) if finite else None


def excursion_metrics(names: tuple[str, ...], estimate: np.ndarray, reference: np.ndarray,
                      t_s: np.ndarray) -> dict[str, object]:
    """``wrench_excursions`` of metrics.json: per component (columns of ``estimate`` and
    ``reference`` named by ``names``) each excursion's start and end time [s], gain and
    RMSE, and the worst gain over every component."""
    out: dict[str, object] = {"fraction_of_peak": EXCURSION_FRACTION}
    every: list[float] = []
    for k, name in enumerate(names):
        found = excursions(estimate[:, k], reference[:, k])
        every += [x.gain for x in found]
        out[name] = [{"start_s": round(float(t_s[x.start]), 4),
                      "end_s": round(float(t_s[x.stop - 1]), 4),
                      "gain": _num(x.gain), "rmse": _num(x.rmse)} for x in found]
    worst = worst_gain(every)
    out["worst_gain"] = None if worst is None else _num(worst)
    out["rest_noise"] = rest_noise(names, estimate, reference)
    return out


def rest_noise(names: tuple[str, ...], estimate: np.ndarray, reference: np.ndarray
               ) -> dict[str, object]:
    """The estimate's standard deviation per component where the gauge reads no load (every
    component at most ``REST_FRACTION`` of its largest |value|), and how many samples."""
    top = np.nanmax(np.abs(reference), axis=0)
    rest = np.all(np.abs(reference) <= REST_FRACTION * top, axis=1)
    values = {name: (_num(float(np.nanstd(estimate[rest, k])))
                     if rest.sum() > 1 and np.isfinite(estimate[rest, k]).any() else None)
              for k, name in enumerate(names)}
    return {"samples": int(rest.sum()), **values}


def _num(x: float) -> float | None:
    return float(f"{x:.6g}") if np.isfinite(x) else None
