"""Contact detection with hysteresis (separate on/off thresholds) and a debounce time."""

from __future__ import annotations

import math

from tactile_sensor.sensing.errors import SensingError


class ContactDetector:
    """Contact turns on after force ≥ ``on_n`` for ``debounce_s``, off after force ≤ ``off_n``
    for ``debounce_s``; in between the state holds. NaN force (no calibration) holds too.
    """

    def __init__(self, on_n: float = 0.5, off_n: float = 0.3, debounce_s: float = 0.01) -> None:
        for name, value in (("contact_on_n", on_n), ("contact_off_n", off_n)):
            if not isinstance(value, int | float) or not math.isfinite(value) or value < 0:
                raise SensingError(f"{name} must be a finite force ≥ 0 N, got {value!r}.")
        if not off_n < on_n:
            raise SensingError(f"contact_off_n ({off_n} N) must be below contact_on_n ({on_n} N) "
                               "so the detector has hysteresis.")
        if not isinstance(debounce_s, int | float) or not 0.0 <= debounce_s <= 10.0:
            raise SensingError(f"contact_debounce_s must be in [0, 10] s, got {debounce_s!r}.")
        self.on_n, self.off_n, self.debounce_s = float(on_n), float(off_n), float(debounce_s)
        self.reset()

    def reset(self) -> None:
        self.contact = False
        self._since: float | None = None  # when the opposite condition started

    def update(self, force_n: float, t_s: float) -> bool:
        """Feed one force at time ``t_s`` [s]; returns the debounced contact state."""
        crossing = force_n <= self.off_n if self.contact else force_n >= self.on_n
        if not crossing:
            self._since = None
            return self.contact
        if self._since is None:
            self._since = t_s
        if t_s - self._since >= self.debounce_s - 1e-9:  # times come from integer µs
            self.contact = not self.contact
            self._since = None
        return self.contact
