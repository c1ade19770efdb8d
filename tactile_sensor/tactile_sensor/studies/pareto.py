"""Non-dominated (Pareto) designs: none of the others is at least as good in every objective
and better in one. O(n^2) comparisons: a study has thousands of designs at most."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt


def pareto_mask(values: npt.ArrayLike, senses: Sequence[str]) -> np.ndarray:
    """Per row of ``values`` (designs x objectives): is it non-dominated? ``senses`` says
    'max' or 'min' per column. Rows with a NaN (failed designs) are never on the front;
    identical rows are all kept (neither dominates the other)."""
    v = np.asarray(values, dtype=float)
    if v.ndim != 2 or v.shape[1] != len(senses):
        raise ValueError("values must be designs x objectives, one sense per objective")
    if any(s not in ("max", "min") for s in senses):
        raise ValueError("each sense must be 'max' or 'min'")
    sign = np.array([1.0 if s == "max" else -1.0 for s in senses])
    score = v * sign                                   # larger is better in every column
    ok = ~np.isnan(score).any(axis=1)
    mask = ok.copy()
    for i in np.flatnonzero(ok):
        others = score[ok]
        dominated = np.all(others >= score[i], axis=1) & np.any(others > score[i], axis=1)
        mask[i] = not dominated.any()
    return mask
