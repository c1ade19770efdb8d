"""The array calibration fitted from a recording (``analyze --fit-calibration`` on an array).

Truth: an 8-module layout whose outputs are a known linear map of the wrench, built in the
calibration's own symmetric features (each feature carries only the components of its
mirror parity), so the fitted calibration must give the wrench back; the gauge's forces
come from the synthetic shear protocol, its torques are slow independent sine waves.
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from tactile_sensor.analysis import cli
from tactile_sensor.analysis.array import fit as af
from tactile_sensor.analysis.array.analysis import ArraySignals
from tactile_sensor.analysis.errors import SegmentError
from tactile_sensor.analysis.synthetic import (
    ArrayTruth,
    ShearProtocol,
    shear_signals,
    with_torque,
    write_array_bag,
)
from tactile_sensor.sensing.array_calibration import (
    COMPONENT_PARITY,
    COMPONENTS,
    ArrayCalibration,
    symmetric_features,
)

FACES = tuple(f"{face}@{c}" for face in ("front", "back", "left", "right")
              for c in ("-0.0055", "0.0055"))
PROTOCOL = ShearProtocol(directions=8, rest_s=1.0)
DEGREE = 2  # enough for the linear truth, and a fit of it takes a tenth of a second


def wrench_map() -> np.ndarray:
    """(modules, 6) outputs per unit wrench [V/N, V/(N m)] respecting the layout's parity."""
    matrix, parity = symmetric_features(FACES)
    a = np.zeros((len(FACES), 6))
    seen: dict[tuple[int, int], int] = {}
    for j, p in enumerate(parity):
        ks = [k for k, c in enumerate(COMPONENTS) if COMPONENT_PARITY[c] == p]
        n = seen.setdefault(p, 0)
        seen[p] += 1
        for i, k in enumerate(ks):  # two features per parity: an invertible 2 x 2 block
            mix = 0.6 if len(ks) == 1 else (-0.5 if n else 0.4)  # pressing raises every module
            a[j, k] = (0.2 if k < 3 else 30.0) * (1.0 if i == n else mix)
    return np.linalg.solve(matrix, a)


def gauge_torque(t_s: np.ndarray, tz_nm: float = 0.005) -> np.ndarray:
    return np.column_stack([0.02 * np.sin(2 * np.pi * t_s / 7.0),
                            0.02 * np.sin(2 * np.pi * t_s / 5.0 + 1.0),
                            tz_nm * np.sin(2 * np.pi * t_s / 4.0)])


def recording(tz_nm: float = 0.005, torque: bool = True, noise_v: float = 0.0,
              tz_scale: float = 1.0):
    """Shear signals whose modules read wrench_map() @ wrench (+ noise; Tz's column times
    ``tz_scale``), with the gauge's torque (and the driver's, equal) when ``torque``."""
    base = shear_signals(PROTOCOL, ArrayTruth(faces=FACES, sensitivity_v_per_n=((0, 0, 0),) * 8,
                                              output_offset_v=(0.0,) * 8))
    t = gauge_torque(base.t_s, tz_nm) if torque else np.zeros((base.t_s.size, 3))
    outputs = np.column_stack([base.reference_n, t]) @ (wrench_map() * np.r_[
        np.ones(5), tz_scale]).T
    outputs += noise_v * np.random.default_rng(3).standard_normal(outputs.shape)
    signals = dataclasses.replace(base, outputs_v=outputs)
    return with_torque(signals, t) if torque else signals


def array_signals(signals) -> ArraySignals:
    return ArraySignals(t_s=signals.t_s, estimate_n=signals.estimate_n,
                        reference_n=signals.reference_n, outputs_v=signals.outputs_v,
                        faces=signals.faces, rate_hz=200.0, start_ns=0, reference_flipped=False,
                        estimate_torque_nm=signals.estimate_torque_nm,
                        reference_torque_nm=signals.reference_torque_nm)


@pytest.fixture(scope="module")
def fitted():
    signals = recording(noise_v=0.002)
    return af.fit_array_signals(array_signals(signals), True, "test", DEGREE), signals


def test_fitted_calibration_recovers_the_known_wrench(fitted):
    fit, signals = fitted
    truth = np.column_stack([signals.reference_n, signals.reference_torque_nm])
    clean = truth @ wrench_map().T
    error = fit.calibration.wrenches(clean) - truth
    span = np.ptp(truth, axis=0)
    assert np.all(np.sqrt(np.mean(error ** 2, axis=0)) < 0.03 * span)
    assert fit.calibration.observed == COMPONENTS
    for c in COMPONENTS:
        pct = fit.metrics["components"][c]["rmse_pct_range"]
        assert 0 < pct < 3.0, (c, pct)
    assert fit.metrics["held_out_samples"] > 0
    assert fit.metrics["force_slow_part"] is False and not fit.calibration.has_slow


def test_a_weak_torque_is_fitted_without_shrinkage():
    """A twist of a few millivolts (Tz's outputs at 3 % of the others') reads at gain 1; the
    fit given 10 mV of torque noise (a ridge) shrinks it."""
    sig = array_signals(recording(noise_v=0.002, tz_scale=0.03))
    truth = sig.reference_torque_nm[:, 2]
    clean = np.column_stack([sig.reference_n, sig.reference_torque_nm]) @ (
        wrench_map() * np.r_[np.ones(5), 0.03]).T

    def gain(fit: af.ArrayFit) -> float:
        return float(np.dot(fit.calibration.wrenches(clean)[:, 5], truth) / np.dot(truth, truth))

    assert af.fit_array_signals(sig, True, "test", DEGREE).metrics["torque_noise_v"] == 0.0
    assert abs(gain(af.fit_array_signals(sig, True, "test", DEGREE)) - 1.0) < 0.03
    assert gain(af.fit_array_signals(sig, True, "test", DEGREE, torque_noise_v=0.010)) < 0.85


def test_held_out_blocks_are_contiguous_and_every_fifth():
    t = np.arange(0, 20, 0.1)
    held = af.held_out_blocks(t)
    assert held.sum() == 2 * 20  # blocks 2 and 7 of ten 2 s blocks
    assert held[(t >= 4) & (t < 6)].all() and not held[t < 4].any()


def test_low_pass_keeps_slow_signal_and_drops_fast_one():
    t = np.arange(0, 20, 0.001)
    slow, fast = np.sin(2 * np.pi * 0.2 * t), 0.5 * np.sin(2 * np.pi * 50 * t)
    ts, out = af.quasi_static(t, (slow + fast)[:, None], 1000.0)
    assert ts.size == out.shape[0] == 200  # decimated to 10 Hz
    inner = slice(10, -10)
    np.testing.assert_allclose(out[inner, 0], np.sin(2 * np.pi * 0.2 * ts)[inner], atol=0.01)


def test_component_not_excited_is_left_out_with_its_line():
    fit = af.fit_array_signals(array_signals(recording(tz_nm=0.0)), True, "test", DEGREE)
    assert "tz" not in fit.calibration.observed
    assert fit.metrics["observed"] == ["fx", "fy", "fz", "tx", "ty"]
    assert np.isnan(fit.calibration.wrench([0.1] * 8)[5])
    line = [x for x in fit.lines if x.startswith("tz")]
    assert len(line) == 1 and "left out of observed" in line[0]
    assert fit.metrics["components"]["tz"]["rmse"] is None


def test_too_few_samples_for_the_degree_is_one_sentence():
    sig = array_signals(clipped(recording(), 2400))  # 12 s: about 100 samples to fit
    four = dataclasses.replace(sig, outputs_v=sig.outputs_v[:, ::2],
                               faces=("front", "back", "left", "right"))
    with pytest.raises(SegmentError) as err:  # degree 8 in 4 modules: Fz has 135 terms
        af.fit_array_signals(four, True, "test", degree=8)
    text = str(err.value)
    assert "lower the degree or record longer" in text
    assert "\n" not in text and text.count(". ") == 0


def clipped(signals, samples: int):
    """The recording's first ``samples`` samples."""
    return dataclasses.replace(signals, **{f.name: getattr(signals, f.name)[:samples] for f in
                                           dataclasses.fields(signals) if f.name in (
                                               "t_s", "reference_n", "estimate_n", "outputs_v",
                                               "reference_torque_nm", "estimate_torque_nm")})


def test_too_short_a_recording_is_one_sentence():
    with pytest.raises(SegmentError, match="too short to hold out"):
        af.fit_array_signals(array_signals(clipped(recording(), 1000)), True, "test")


def test_no_per_module_outputs_is_one_sentence():
    signals = recording()
    sig = dataclasses.replace(array_signals(signals), outputs_v=np.empty((signals.t_s.size, 0)),
                              faces=())
    with pytest.raises(SegmentError, match="no per-module outputs"):
        af.fit_array_signals(sig, True, "test")


@pytest.mark.parametrize("torque", [True, False])
def test_cli_writes_a_loadable_file_metrics_and_a_line_per_component(tmp_path, capsys, torque):
    bag = write_array_bag(tmp_path / "bag", recording(torque=torque), "mcap")
    out = tmp_path / "out"
    assert cli.main([str(bag), "--out", str(out), "--fit-calibration", "--no-figures",
                     "--prediction", "none"]) == 0
    cal = ArrayCalibration.from_file(out / "calibration.json")
    assert cal.faces == FACES and cal.has_torque == torque
    assert cal.observed == (COMPONENTS if torque else COMPONENTS[:3])
    mt = json.loads((out / "metrics.json").read_text())["array_calibration_fit"]
    assert list(mt["components"]) == list(COMPONENTS if torque else COMPONENTS[:3])
    assert all(c["rmse_pct_range"] < 3.0 for c in mt["components"].values())
    err = capsys.readouterr().err
    lines = [x for x in err.splitlines() if "array calibration" in x]
    assert len(lines) == (6 if torque else 4)
    assert ("the gauge measures no torque" in err) != torque
    assert "Array calibration fitted from this recording" in (out / "report.md").read_text()
