"""The wrench protocol's probe path and its overrides."""

from __future__ import annotations

import numpy as np
import pytest

from tactile_sensor.sim.errors import SimError
from tactile_sensor.sim.profiles import WrenchProfile, array_profile, array_profile_from_protocol


def test_protocol_wrench_presses_shears_tilts_twists_and_combines() -> None:
    profile = array_profile_from_protocol("wrench")
    assert isinstance(profile, WrenchProfile)
    assert profile.duration_s == pytest.approx(84.0)   # the duration protocols.yaml names
    times, pts = profile.knots()
    assert pts[0] == pytest.approx(np.zeros(6)) and pts[-1] == pytest.approx(np.zeros(6))
    moved = pts[np.any(pts[:, 1:] != 0, axis=1)]
    assert np.all(moved[:, 0] == pytest.approx(0.003))          # every move at full depth
    for axis, amount in ((1, 0.003), (2, 0.003), (3, 0.1), (4, 0.1), (5, 0.2)):
        assert moved[:, axis].max() == pytest.approx(amount)
        assert moved[:, axis].min() == pytest.approx(-amount)
    together = np.count_nonzero(moved[:, 1:], axis=1)
    assert together.max() == 2 and np.count_nonzero(together == 2) == 3
    rates = np.abs(np.diff(pts[:, 3:], axis=0)) / np.maximum(np.diff(times), 1e-12)[:, None]
    assert rates.max() == pytest.approx(0.05)
    assert profile.rotation(times[-1]) == pytest.approx((0.0, 0.0, 0.0))


def test_overrides_change_the_amplitudes() -> None:
    profile = array_profile_from_protocol("wrench", tilt_rad=0.05, twist_rad=0.1,
                                          angular_speed_rad_s=0.1)
    _, pts = profile.knots()
    assert np.abs(pts[:, 3]).max() == pytest.approx(0.05)
    assert np.abs(pts[:, 5]).max() == pytest.approx(0.1)
    assert profile.duration_s < array_profile_from_protocol("wrench").duration_s


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"tilt_rad": 0.6}, "tilt must be within"),
    ({"twist_rad": -0.1}, "twist must be within"),
    ({"twist_rad": 0.1, "angular_speed_rad_s": 0.0}, "angular_speed must be within"),
    ({"twist_rad": 0.1, "speeds_m_s": (0.001, 0.002)}, "one speed from contact"),
    ({"twist_rad": 0.1, "preload_m": 0.001}, "one speed from contact"),
])
def test_bad_wrench_overrides_are_refused_in_one_sentence(kwargs: dict, match: str) -> None:
    with pytest.raises(SimError, match=match) as info:
        array_profile(**kwargs)
    assert str(info.value).count(". ") == 0 and str(info.value).endswith(".")


def test_without_rotation_the_shear_protocol_is_unchanged() -> None:
    assert type(array_profile_from_protocol("shear")).__name__ == "ShearProfile"
    assert array_profile_from_protocol("shear").duration_s == pytest.approx(104.0)
