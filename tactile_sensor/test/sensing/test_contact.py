from __future__ import annotations

import pytest

from tactile_sensor.sensing.contact import ContactDetector
from tactile_sensor.sensing.errors import SensingError


def feed(det, forces, dt=0.001, t0=0.0):
    return [det.update(f, t0 + i * dt) for i, f in enumerate(forces)]


def test_debounce_and_hysteresis():
    det = ContactDetector(on_n=0.5, off_n=0.3, debounce_s=0.005)
    # a 3 ms spike above 'on' is ignored
    assert not any(feed(det, [0.0, 0.6, 0.6, 0.6, 0.0]))
    states = feed(det, [0.6] * 10, t0=1.0)
    assert states.index(True) == 5  # after 5 ms held
    # between the thresholds the contact holds
    assert all(feed(det, [0.4] * 50, t0=2.0))
    states = feed(det, [0.2] * 10, t0=3.0)
    assert states.index(False) == 5


def test_nan_force_holds_the_state():
    det = ContactDetector(debounce_s=0.0)
    assert det.update(1.0, 0.0)
    assert det.update(float("nan"), 0.1)


@pytest.mark.parametrize(("kw", "match"), [({"on_n": 0.3, "off_n": 0.5}, "below contact_on_n"),
                                           ({"on_n": -1.0}, "contact_on_n"),
                                           ({"off_n": float("nan")}, "contact_off_n"),
                                           ({"debounce_s": -0.1}, "contact_debounce_s")])
def test_bad_settings(kw, match):
    with pytest.raises(SensingError, match=match):
        ContactDetector(**kw)
