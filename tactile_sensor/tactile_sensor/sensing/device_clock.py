"""Device clock -> host clock, so each force is stamped with the time it was sampled.

The ADC stamps frames in device microseconds; the host learns of a frame some variable
time later (USB polling, scheduling). The smallest ``host - device`` difference seen is the
best estimate of the clock offset (it is the frame that waited least). The estimate leaks
upward slowly so a device clock running slow or fast is followed, and restarts when the
reader reports a new connection epoch (the device may have rebooted).
"""

from __future__ import annotations


class DeviceClock:
    def __init__(self, max_drift_ppm: float = 200.0) -> None:
        if not 0.0 <= max_drift_ppm <= 10_000.0:
            raise ValueError(f"max_drift_ppm must be in 0..10000, got {max_drift_ppm!r}.")
        self._leak = max_drift_ppm * 1e-6
        self._epoch: int | None = None
        self._offset_ns = 0
        self._last_device_ns = 0

    def stamp_ns(self, epoch: int, device_time_us: int, host_time_ns: int) -> int:
        """Host-clock time [ns] at which the device took this sample."""
        device_ns = device_time_us * 1000
        observed = host_time_ns - device_ns
        if epoch != self._epoch:
            self._epoch, self._offset_ns = epoch, observed
        else:
            elapsed = max(0, device_ns - self._last_device_ns)
            self._offset_ns = min(self._offset_ns + int(elapsed * self._leak), observed)
        self._last_device_ns = device_ns
        return device_ns + self._offset_ns
