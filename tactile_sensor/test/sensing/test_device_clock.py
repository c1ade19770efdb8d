from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from tactile_sensor.sensing.device_clock import DeviceClock


@given(st.lists(st.integers(min_value=100_000, max_value=3_000_000), min_size=5, max_size=200))
def test_stamps_recover_the_smallest_latency_and_never_lie_in_the_future(latencies_ns):
    clock = DeviceClock(max_drift_ppm=0.0)
    start = 1_700_000_000_000_000_000
    stamps = []
    for i, latency in enumerate(latencies_ns):
        device_us = 5_000 + i * 1000
        host = start + device_us * 1000 + latency
        stamp = clock.stamp_ns(0, device_us, host)
        assert stamp <= host
        stamps.append((stamp, start + device_us * 1000))
    best = min(latencies_ns)
    last_stamp, true_time = stamps[-1]
    assert last_stamp - true_time == best


def test_a_new_epoch_reanchors_the_offset():
    clock = DeviceClock()
    clock.stamp_ns(0, 1_000_000, 10_000_000_000)
    # device rebooted: its clock restarts at zero
    assert clock.stamp_ns(1, 0, 20_000_000_000) == 20_000_000_000


def test_drift_is_followed():
    clock = DeviceClock(max_drift_ppm=200.0)
    host0 = 1_000_000_000_000
    # device clock 100 ppm slow: host advances 1.0001 s per device second; latency 0.2 ms.
    # Over 20 s an unfollowed drift would put stamps 2 ms off; the error must stay at the
    # (unobservable, constant) latency absorbed at the start.
    for i in range(2000):
        device_us = i * 10_000
        true_ns = host0 + int(device_us * 1000 * 1.0001)
        stamp = clock.stamp_ns(0, device_us, true_ns + 200_000)
    assert stamp - true_ns == pytest.approx(200_000, abs=20_000)


def test_bad_drift_bound_is_refused():
    with pytest.raises(ValueError, match="max_drift_ppm"):
        DeviceClock(max_drift_ppm=-1.0)
