"""The slip study's computations: resolution from the noise and a layout's sensitivity,
Rice's false-alarm threshold, the slip signatures of the held-object model and the margin
detector, on small synthetic layouts and skins (no FEM solve)."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tactile_sensor.analysis.errors import AnalysisError
from tactile_sensor.analysis.slip.detector import MarginDetector, detection_delay_s
from tactile_sensor.analysis.slip.resolution import (
    crossing_rate_hz,
    force_covariance,
    local_sensitivity,
    resolution,
    threshold_sigmas,
)
from tactile_sensor.analysis.slip.signature import (
    Scenario,
    SlipTrace,
    band_rms,
    least_grip_n,
    sense,
    shear_coupling,
    simulate,
    white_band_rms,
)
from tactile_sensor.analysis.slip.study import Skin, as_row, evaluate
from tactile_sensor.sim.skin_shear import TangentialStiffness

#: Four modules, opposite pairs: left/right read Fx, front/back Fy, all Fz [V/N].
FOUR = np.array([[0.0, 0.1, 0.05], [0.0, -0.1, 0.05], [-0.1, 0.0, 0.05], [0.1, 0.0, 0.05]])
STIFF = TangentialStiffness([0.0005, 0.003], [350.0, 314.0])


@given(noise=st.floats(0.005, 0.1), hz=st.floats(5.0, 200.0), grip=st.floats(0.5, 10.0))
@settings(max_examples=30, deadline=None)
def test_resolution_scales_with_noise_bandwidth_and_grip(noise: float, hz: float,
                                                         grip: float) -> None:
    base = resolution(FOUR, hz, grip, sample_noise_v=noise)
    assert resolution(FOUR, hz, grip, sample_noise_v=2 * noise).tangential_n == \
        pytest.approx(2 * base.tangential_n)
    assert resolution(FOUR, 2 * hz, grip, sample_noise_v=noise).tangential_n == \
        pytest.approx(math.sqrt(2) * base.tangential_n)
    assert resolution(FOUR, hz, 2 * grip, sample_noise_v=noise).resolved_ratio == \
        pytest.approx(0.5 * base.resolved_ratio)


def test_force_noise_is_the_least_squares_one() -> None:
    cov = force_covariance(FOUR, 0.01)
    # Fx from the left/right difference: 0.01 / (0.1 sqrt 2); Fz from four at 0.05 V/N
    assert math.sqrt(cov[0, 0]) == pytest.approx(0.01 / (0.1 * math.sqrt(2)))
    assert math.sqrt(cov[2, 2]) == pytest.approx(0.01 / (0.05 * 2))


def test_one_module_cannot_see_shear() -> None:
    one = FOUR[:1]
    cov = force_covariance(one, 0.01)
    assert math.isinf(cov[0, 0]) and math.isinf(cov[1, 1]) and math.isinf(cov[2, 2])
    assert math.isinf(resolution(one, 30.0, 2.0).resolved_ratio)
    # a press-only module reads the normal force alone
    press = np.array([[0.0, 0.0, 0.05]])
    assert math.isinf(force_covariance(press, 0.01)[0, 0])
    assert force_covariance(press, 0.01)[2, 2] == pytest.approx((0.01 / 0.05) ** 2)


def test_threshold_matches_rices_rate_on_simulated_noise() -> None:
    from scipy.signal import butter, lfilter

    hz, k = 20.0, 2.0
    b, a = butter(2, hz / 500.0)
    rng = np.random.default_rng(0)
    x = lfilter(b, a, rng.normal(size=200_000))[1000:]
    x /= x.std()
    ups = np.count_nonzero((x[1:] > k) & (x[:-1] <= k)) / (x.size / 1000.0)
    assert ups == pytest.approx(crossing_rate_hz(k, hz), rel=0.15)
    # and the inverse: k for a rate gives that rate back
    assert crossing_rate_hz(threshold_sigmas(3600.0, hz), hz) == pytest.approx(1.0)
    assert threshold_sigmas(1.0, 100.0) > threshold_sigmas(1.0, 10.0)
    assert threshold_sigmas(1.0, 10.0, two_sided=True) > threshold_sigmas(1.0, 10.0)


@dataclass
class FakeGrid:
    """A grid as ``ArrayGrid`` looks to the study: linear outputs, quadratic coupling."""

    sensitivity: np.ndarray
    coupling: float = 0.0

    def __post_init__(self) -> None:
        steps, levels, dirs = 6, 3, 4
        rows = [(k, j, i) for k in range(1, steps + 1) for j in range(levels + 1)
                for i in (range(dirs) if j else [0])]
        self.step = np.array([r[0] for r in rows])
        self.level = np.array([r[1] for r in rows])
        self.direction = np.array([r[2] for r in rows])
        self.indentation_m = self.step * 0.0005
        angle = self.direction * math.pi / 2
        s = self.level * self.indentation_m
        self.shear_x_m = s * np.cos(angle)
        self.shear_y_m = s * np.sin(angle)
        fz = 2000.0 * self.indentation_m - self.coupling * s**2
        self.force_n = fz
        self._forces = np.column_stack([300 * self.shear_x_m, 300 * self.shear_y_m, fz])

    def force_matrix(self) -> np.ndarray:
        return self._forces

    def output_matrix(self) -> np.ndarray:
        return self._forces @ self.sensitivity.T + 0.01


def test_local_sensitivity_and_coupling_from_a_grid() -> None:
    grid = FakeGrid(FOUR, coupling=2000.0)
    assert local_sensitivity(grid, 0.001) == pytest.approx(FOUR, abs=1e-9)
    assert shear_coupling(grid, 0.0012) == pytest.approx(2000.0)
    empty = FakeGrid(FOUR)
    empty.step = np.zeros_like(empty.step)
    with pytest.raises(AnalysisError, match="no pressed point"):
        local_sensitivity(empty, 0.001)
    with pytest.raises(AnalysisError, match="no pressed point"):
        shear_coupling(empty, 0.001)


def scenario(grip_factor: float, double: bool = True, mu_k: float = 0.5) -> Scenario:
    """100 g at static friction 0.5, held at ``grip_factor`` x the least grip that keeps
    the doubled load."""
    base = Scenario(0.1, 0.5, mu_k, 1.0, double=double, hold_s=0.3, after_s=0.2)
    return replace(base, grip_n=grip_factor * least_grip_n(2 * base.weight_n, 0.5))


def test_simulated_slip_and_stick() -> None:
    slip = simulate(scenario(0.8), STIFF, 0.001)
    assert slip.onset_s is not None and slip.onset_s >= scenario(0.8).double_at_s
    assert slip.slip_m[-1] > 1e-3
    # after the onset the shear stops growing at the kinetic limit
    after = slip.t_s > slip.onset_s + 0.01
    assert np.abs(slip.ft_n[after]).max() == pytest.approx(0.5 * scenario(0.8).grip_n)
    stick = simulate(scenario(1.6), STIFF, 0.001)
    assert stick.onset_s is None and abs(stick.slip_m[-1]) < 1e-9
    with pytest.raises(AnalysisError, match="grip"):
        simulate(replace(scenario(1.0), grip_n=0.0), STIFF, 0.001)


def test_normal_force_falls_with_the_shear_coupling() -> None:
    plain = simulate(scenario(1.6), STIFF, 0.001)
    coupled = simulate(scenario(1.6), STIFF, 0.001, coupling_n_per_m2=2000.0)
    assert np.all(coupled.fn_n <= plain.fn_n)
    assert (plain.fn_n - coupled.fn_n).max() > 0


def test_band_rms_finds_a_tone_in_its_band() -> None:
    t = np.arange(2000) / 1000.0
    tone = np.sin(2 * math.pi * 100 * t)
    assert band_rms(tone, (50, 200)) == pytest.approx(1 / math.sqrt(2), rel=0.05)
    assert band_rms(tone, (200, 490)) < 0.05
    assert white_band_rms(1.0, (0.001, 500.0)) == pytest.approx(1.0, rel=1e-3)
    with pytest.raises(AnalysisError, match="band"):
        band_rms(tone, (200, 100))


def noisy(trace: SlipTrace, sigma: float = 0.02, seed: int = 0
          ) -> tuple[np.ndarray, np.ndarray]:
    return sense(trace, np.diag([sigma**2, sigma**2]), np.random.default_rng(seed))


def test_detector_fires_on_slip_and_not_on_a_stick_only_hold() -> None:
    detector = MarginDetector(friction=0.5, bandwidth_hz=20.0, threshold_n=0.08)
    slip = simulate(scenario(0.8), STIFF, 0.001)
    delay = detection_delay_s(detector, slip.t_s, *noisy(slip), slip.onset_s,
                              scenario(0.8).double_at_s)
    assert delay is not None and delay < 0.03
    stick = simulate(scenario(1.6), STIFF, 0.001)
    assert detector.alarms(*noisy(stick)) == 0
    assert detector.first_alarm(*noisy(stick)) is None
    # a detector that believes the friction higher than it is warns later or never
    blind = MarginDetector(friction=5.0, bandwidth_hz=20.0, threshold_n=0.08)
    assert detection_delay_s(blind, slip.t_s, *noisy(slip), slip.onset_s) is None


def test_detector_refuses_bad_settings() -> None:
    for bad in ({"friction": 0.0}, {"friction": math.nan}, {"bandwidth_hz": 0.0},
                {"bandwidth_hz": 600.0}):
        with pytest.raises(AnalysisError, match="detector"):
            MarginDetector(**{"friction": 0.5, "bandwidth_hz": 20.0, "threshold_n": 0.1,
                              **bad})
    with pytest.raises(AnalysisError, match="false-alarm"):
        threshold_sigmas(0.0, 10.0)
    with pytest.raises(AnalysisError, match="grip"):
        resolution(FOUR, 10.0, 0.0)


def test_threshold_follows_the_margin_noise() -> None:
    res = resolution(FOUR, 30.0, 2.0)
    detector = MarginDetector.for_resolution(0.5, res)
    assert detector.threshold_n == pytest.approx(
        res.k * math.hypot(res.sigma_n[0], 0.5 * res.sigma_n[2]))
    assert detector.least_margin_n() == pytest.approx(2 * detector.threshold_n)


def test_evaluate_holds_at_the_detectors_margin_and_sees_the_slip() -> None:
    skin = Skin(STIFF, lambda f: f / 2000.0, lambda _d: FOUR)
    heavy = Scenario(0.3, 0.5, 0.4, 1.0, hold_s=0.3, after_s=0.2)
    fig = evaluate(heavy, skin, 20.0, np.random.default_rng(1))
    margin = heavy.friction_kinetic * fig.grip_n - 0.5 * heavy.weight_n
    assert margin == pytest.approx(fig.least_margin_n)
    assert fig.onset_s is not None and fig.delay_s is not None and fig.delay_s < 0.03
    assert fig.rest_alarms == 0
    assert fig.plateau_s is not None and fig.plateau_s > 0
    row = as_row(heavy, fig)
    assert row["bandwidth_hz"] == 20.0 and row["delay_ms"] == pytest.approx(fig.delay_s * 1e3)


def test_a_friction_believed_too_high_grips_less_and_warns_later() -> None:
    skin = Skin(STIFF, lambda f: f / 2000.0, lambda _d: FOUR)
    heavy = Scenario(0.3, 0.5, 0.4, 1.0, hold_s=0.3, after_s=0.2)
    right = evaluate(heavy, skin, 20.0, np.random.default_rng(1))
    high = evaluate(heavy, skin, 20.0, np.random.default_rng(1), learned=1.2)
    assert high.grip_n < right.grip_n
    assert high.delay_s is not None and right.delay_s is not None
    assert high.delay_s > right.delay_s
