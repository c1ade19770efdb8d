from __future__ import annotations

import numpy as np
import pytest

from tactile_sensor.sensing.errors import SensingError, TareError
from tactile_sensor.sensing.tare import TareWindow


def fill(window, values):
    for v in values:
        window.add(float(v))
    return window


def test_noisy_rest_is_accepted_with_the_mean_as_baseline():
    rng = np.random.default_rng(0)
    values = 1.98 + rng.normal(0.0, 0.039, 500)  # the paper-level noise
    result = fill(TareWindow(1000.0, 0.5, 0.05), values).evaluate()
    assert result.baseline_v == pytest.approx(values.mean())
    assert result.samples == 500
    # what the driver logs on a tare
    assert result.describe() == (f"baseline {result.baseline_v:.4f} V "
                                 f"(spread {result.spread_v * 1e3:.1f} mV)")
    assert result.describe().startswith("baseline 1.97")


def test_a_press_in_progress_is_refused():
    rng = np.random.default_rng(0)
    ramp = 1.98 - 0.16 * np.arange(500) / 1000.0  # 1 mm/s press: ~0.16 V/s
    window = fill(TareWindow(1000.0, 0.5, 0.05), ramp + rng.normal(0.0, 0.039, 500))
    with pytest.raises(TareError, match="not at rest"):
        window.evaluate()


def test_too_few_samples_are_refused_and_nan_is_never_at_rest():
    window = fill(TareWindow(1000.0, 0.5, 0.05), [1.0] * 100)
    with pytest.raises(TareError, match="only 100"):
        window.evaluate()
    fill(window, [float("nan")] * 500)
    with pytest.raises(TareError, match="not at rest"):
        window.evaluate()


@pytest.mark.parametrize(("window_s", "spread", "match"), [(0.0, 0.05, "tare_window_s"),
                                                          (0.5, 0.0, "tare_max_spread_v")])
def test_bad_settings(window_s, spread, match):
    with pytest.raises(SensingError, match=match):
        TareWindow(1000.0, window_s, spread)
