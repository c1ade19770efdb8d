"""Module arrays: the driver's wrench against the gauge, the sensitivity matrix and the shear
direction, from real bags (sqlite3 and MCAP) of the shear protocol with a known truth.

Truth (synthetic.ArrayTruth): gauge force from the stage (Fz = 6 N (d/2 mm)^1.2, lateral
400 N/m of probe displacement), outputs = S F + c exactly (S faces x axes, V/N), the
driver's estimate = gauge + a chosen offset + chosen noise. With no noise the metrics are
exact: the tolerances below are metrics.json's 6 significant figures.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from rosbags.rosbag2 import Writer
from rosbags.typesys import get_types_from_msg

from tactile_sensor.analysis import characterise as ch
from tactile_sensor.analysis.array import analysis as arr
from tactile_sensor.analysis.bag_reader import Recording, Series
from tactile_sensor.analysis.report import array_lines
from tactile_sensor.analysis.synthetic import (
    ARRAY_SENSITIVITY_V_PER_N,
    JOINT_TYPE,
    READING_TYPE,
    WRENCH_TYPE,
    ArrayTruth,
    PressProtocol,
    SensorTruth,
    ShearProtocol,
    press_signals,
    serialize_many,
    shear_signals,
    with_torque,
    write_array_bag,
    write_press_bag,
    writer_typestore,
)

PROTOCOL = ShearProtocol()
OFFSET = (0.1, -0.2, 0.05)
ARRAY_FIGURES = {"array_force_time.png", "array_force_scatter.png", "array_crosstalk.png",
                 "array_shear_direction.png"}
PAPER_FIGURES = {"force_vs_indentation.png", "output_vs_indentation.png",
                 "output_vs_force.png", "cycles.png", "first_last_cycles.png", "speeds.png"}


def analysed(tmp_path, signals, storage="sqlite3", **options):
    bag = write_array_bag(tmp_path / f"bag-{storage}", signals, storage)
    return ch.analyse(str(bag), ch.Options(**options)), bag


@pytest.fixture(scope="module", params=["sqlite3", "mcap"])
def exact(request, tmp_path_factory):
    """A noise-free shear recording whose driver estimate is the gauge plus OFFSET."""
    signals = shear_signals(PROTOCOL, ArrayTruth(estimate_offset_n=OFFSET))
    bag = write_array_bag(tmp_path_factory.mktemp(request.param) / "shear", signals,
                          request.param)
    return ch.analyse(str(bag), ch.Options()), signals, request.param


def test_offset_gives_that_rmse_and_ranges_are_the_gauges(exact):
    result, signals, storage = exact
    mt = result.metrics
    assert mt["storage"] == storage
    for j, axis in enumerate("xyz"):
        assert mt["force_rmse_n"][axis] == pytest.approx(abs(OFFSET[j]), rel=1e-5)
        ref = signals.reference_n[:, j]
        assert mt["force_range_n"][axis] == pytest.approx(ref.max() - ref.min(), rel=1e-5)
    # the stage reaches 3 mm sideways at 400 N/m: 1.2 N both ways; 6 N pressing
    assert mt["force_range_n"] == pytest.approx({"x": 2.4, "y": 2.4, "z": 6.0}, rel=1e-5)
    assert mt["force_rmse_pct_range"]["z"] == pytest.approx(100 * 0.05 / 6.0, rel=1e-5)


def test_known_sensitivity_matrix_is_recovered(exact):
    mt = exact[0].metrics["array"]
    sens = mt["sensitivity_matrix"]
    assert sens["faces"] == ["front", "back", "left", "right"]
    assert sens["axes"] == ["x", "y", "z"]
    np.testing.assert_allclose(sens["values_v_per_n"], ARRAY_SENSITIVITY_V_PER_N, atol=1e-9)
    np.testing.assert_allclose(sens["offset_v"], ArrayTruth().output_offset_v, atol=1e-9)
    np.testing.assert_allclose(sens["r2"], 1.0, atol=1e-9)
    assert mt["excited_axes"] == ["x", "y", "z"]


def test_offset_estimate_has_no_cross_talk_and_exact_directions(exact):
    mt = exact[0].metrics["array"]
    np.testing.assert_allclose(mt["force_cross_talk"]["values"], np.eye(3), atol=1e-9)
    sd = mt["shear_direction"]
    # a constant lateral offset turns the estimated direction; largest where the lateral
    # force is smallest (the threshold, 0.2 x 1.2 N), so compute what it must be
    assert sd["threshold_n"] == pytest.approx(0.24, rel=1e-5)
    assert sd["max_abs_deg"] > 1.0
    assert sd["samples"] > 100


def test_a_press_in_an_array_recording_still_gives_the_papers_metrics(exact):
    mt = exact[0].metrics
    assert mt["cycles"] == 1
    assert mt["reference_speed_mm_s"] == 2.0
    # 'output' is the front module's: 0.05 V/N along z, and Fx = Fy = 0 while pressing
    assert mt["sensitivity_v_per_n"] == pytest.approx(0.05, rel=1e-3)
    assert mt["full_scale_n"] == pytest.approx(6.0, rel=1e-3)
    assert any("analysed as a module array" in n for n in mt["notes"])


def test_noise_gives_its_own_rmse_and_directions_within_noise(tmp_path):
    truth = ArrayTruth(estimate_noise_n=(0.03, 0.05, 0.1), output_noise_v=0.002)
    signals = shear_signals(dataclasses.replace(PROTOCOL, directions=8), truth, seed=4)
    result, _ = analysed(tmp_path, signals, "mcap")
    mt = result.metrics
    want = np.sqrt(np.mean(signals.estimate_noise_n ** 2, axis=0))
    for j, axis in enumerate("xyz"):
        assert mt["force_rmse_n"][axis] == pytest.approx(want[j], rel=1e-5)
    np.testing.assert_allclose(mt["array"]["sensitivity_matrix"]["values_v_per_n"],
                               ARRAY_SENSITIVITY_V_PER_N, atol=2e-3)  # noise 2 mV
    talk = np.array(mt["array"]["force_cross_talk"]["values"])
    np.testing.assert_allclose(talk, np.eye(3), atol=0.02)
    sd = mt["array"]["shear_direction"]
    # 0.05 N of noise across at least 0.24 N: ~ atan(0.05/0.24) = 12 deg at worst RMS
    assert sd["rmse_deg"] < 12.0
    assert result.array.shear.applied_rad.size == sd["samples"]


def test_no_press_gives_the_array_metrics_and_says_why_the_papers_are_missing(tmp_path):
    signals = shear_signals(dataclasses.replace(PROTOCOL, press=False),
                            ArrayTruth(estimate_offset_n=OFFSET))
    result, _ = analysed(tmp_path, signals, fit_calibration=True)
    mt = result.metrics
    assert result.single is None and result.fitted is None
    assert mt["cycles"] == 0 and mt["sensitivity_v_per_n"] is None
    assert mt["force_rmse_n"]["x"] == pytest.approx(0.1, rel=1e-5)
    assert any("does not apply" in n and "never changes" in n for n in mt["notes"])
    # the null metrics carry exactly the keys a characterised recording has
    single = ch.analyse_bag(str(write_press_bag(
        tmp_path / "single", press_signals(PressProtocol(cycles=(2,), rate_hz=200.0),
                                           SensorTruth()))), ch.Options())
    assert set(single.metrics) <= set(mt)


def test_nan_before_the_tare_is_left_out(tmp_path):
    signals = shear_signals(dataclasses.replace(PROTOCOL, untared_s=0.5),
                            ArrayTruth(estimate_offset_n=OFFSET))
    mt = analysed(tmp_path, signals)[0].metrics
    assert mt["force_rmse_n"]["y"] == pytest.approx(0.2, rel=1e-5)
    assert mt["array"]["duration_s"] == pytest.approx(signals.t_s[-1] - 0.5, abs=0.01)


def test_compression_only_leaves_unexcited_axes_out(tmp_path):
    signals = shear_signals(dataclasses.replace(PROTOCOL, directions=0), ArrayTruth())
    mt = analysed(tmp_path, signals)[0].metrics
    ar = mt["array"]
    assert ar["excited_axes"] == ["z"]
    assert mt["force_range_n"]["x"] == 0.0
    values = np.array(ar["sensitivity_matrix"]["values_v_per_n"], dtype=float)
    assert np.all(np.isnan(values[:, :2]))
    np.testing.assert_allclose(values[:, 2], 0.05, atol=1e-9)
    assert ar["shear_direction"] is None
    assert any("hardly varies along x, y" in n for n in mt["notes"])


def test_single_module_recording_is_analysed_exactly_as_before(tmp_path):
    """No 'array' key, and the same metrics whether or not the bag also holds a driver
    wrench without lateral force (a single-module driver's)."""
    signals = press_signals(PressProtocol(cycles=(2,), rate_hz=200.0), SensorTruth(), seed=2)
    bag = write_press_bag(tmp_path / "single", signals)
    result = ch.analyse(str(bag), ch.Options())
    assert result.array is None and "array" not in result.metrics
    assert "force_rmse_n" not in result.metrics
    before = ch.analyse_bag(str(bag), ch.Options()).metrics
    assert result.metrics == before
    assert set(before["topics"]) == {"reading", "reference", "position"}


# --- torque ----------------------------------------------------------------------------------

TORQUE_OFFSET = (0.002, -0.001, 0.0005)  # N m


def gauge_torque(signals):
    """A gauge torque exciting all three axes: the lateral force at a 10 mm lever (tilt)
    and a twist of 5 mN m amplitude."""
    f = signals.reference_n
    return np.column_stack([-0.01 * f[:, 1], 0.01 * f[:, 0],
                            0.005 * np.sin(2 * np.pi * signals.t_s / 4.0)])


def test_known_torque_error_gives_that_rmse_and_the_gauges_range(tmp_path):
    signals = shear_signals(dataclasses.replace(PROTOCOL, untared_s=0.5),
                            ArrayTruth(estimate_offset_n=OFFSET))
    torque = gauge_torque(signals)
    result, _ = analysed(tmp_path, with_torque(signals, torque, TORQUE_OFFSET), "mcap")
    mt = result.metrics
    for j, axis in enumerate("xyz"):
        assert mt["torque_rmse_nm"][axis] == pytest.approx(abs(TORQUE_OFFSET[j]), rel=1e-5)
    # 1.2 N of lateral force both ways at 10 mm: 24 mN m; the twist +-5 mN m
    assert mt["torque_range_nm"] == pytest.approx({"x": 0.024, "y": 0.024, "z": 0.01},
                                                  rel=1e-3)
    assert mt["torque_rmse_pct_range"]["x"] == pytest.approx(100 * 0.002 / 0.024, rel=1e-3)
    assert mt["array"]["torque_unobserved_axes"] == []
    assert mt["force_rmse_n"]["y"] == pytest.approx(0.2, rel=1e-5)  # the force as before


def test_torque_the_driver_publishes_as_nan_is_null_with_a_reason(tmp_path):
    signals = shear_signals(PROTOCOL, ArrayTruth())
    torque = gauge_torque(signals)
    result, _ = analysed(tmp_path, with_torque(signals, torque, TORQUE_OFFSET, ("x", "y")))
    mt = result.metrics
    assert mt["torque_rmse_nm"]["x"] is None and mt["torque_rmse_nm"]["y"] is None
    assert mt["torque_rmse_pct_range"]["x"] is None and mt["torque_rmse_pct_range"]["y"] is None
    assert mt["torque_rmse_nm"]["z"] == pytest.approx(0.0005, rel=1e-5)
    assert mt["torque_range_nm"]["x"] == pytest.approx(0.024, rel=1e-3)  # what was applied
    assert mt["array"]["torque_unobserved_axes"] == ["x", "y"]
    reasons = [n for n in mt["notes"] if "Tx, Ty as NaN" in n]
    assert len(reasons) == 1 and "does not observe" in reasons[0]
    json.dumps(mt, allow_nan=False)  # null, not NaN, in metrics.json
    table = "\n".join(array_lines(mt))
    assert "| Tx | not observed" in table and "| Tz | 0.0005 N m |" in table


def test_a_recording_without_torque_has_no_torque_keys_or_figures(exact, tmp_path):
    mt = exact[0].metrics
    assert not any(k.startswith("torque") for k in mt)
    assert "torque_unobserved_axes" not in mt["array"]
    assert not any("torque" in n for n in mt["notes"])
    assert exact[0].array.signals.estimate_torque_nm is None


def test_torque_on_one_side_only_is_not_compared_and_says_why(tmp_path):
    signals = shear_signals(PROTOCOL, ArrayTruth())
    gauge_only = dataclasses.replace(signals, reference_torque_nm=gauge_torque(signals))
    mt = analysed(tmp_path, gauge_only)[0].metrics
    assert "torque_rmse_nm" not in mt
    assert any("measures torque but the driver's wrench on /driver/wrench carries none" in n
               for n in mt["notes"])


def test_detection_reads_the_data():
    def rec(k, lateral):
        reading = Series("/r", "T", np.arange(3), {}, "header",
                            arrays={"outputs_v": np.zeros((3, k))})
        est = Series("/w", "W", np.arange(3),
                        {"force_x_n": np.array([0.0, lateral, np.nan]),
                         "force_y_n": np.zeros(3), "force_n": np.ones(3)}, "header")
        return Recording(path=Path("b"), storage="mcap",
                            series={"reading": reading, "estimate": est})

    assert arr.detect(rec(0, 0.0)) is None
    assert arr.detect(rec(1, 0.0)) is None
    assert "4 modules" in arr.detect(rec(4, 0.0))
    assert "lateral force" in arr.detect(rec(0, 0.3))


# --- the CLI end to end ------------------------------------------------------------------

@pytest.mark.slow
@pytest.mark.parametrize("press", [True, False])
def test_cli_writes_the_array_metrics_figures_and_report(run, tmp_path, capsys, press):
    signals = shear_signals(dataclasses.replace(PROTOCOL, press=press, directions=8),
                            ArrayTruth(estimate_offset_n=OFFSET, estimate_noise_n=(0.02,) * 3))
    if not press:  # and a driver that observes only the twist
        signals = with_torque(signals, gauge_torque(signals), TORQUE_OFFSET, ("x", "y"))
    bag = write_array_bag(tmp_path / "bag", signals, "mcap")
    out = tmp_path / "out"
    code, err = run([str(bag), "--out", str(out), "--prediction", "none"], capsys)
    assert code == 0, err
    names = {p.name for p in out.iterdir()}
    assert ARRAY_FIGURES | {"metrics.json", "report.md", "report.html"} <= names
    assert (names >= PAPER_FIGURES) == press
    mt = json.loads((out / "metrics.json").read_text())
    assert {"force_rmse_n", "force_range_n", "force_rmse_pct_range", "array"} <= set(mt)
    assert set(mt["force_rmse_n"]) == set(mt["force_range_n"]) == {"x", "y", "z"}
    assert {"detected_by", "faces", "sensitivity_matrix", "force_cross_talk",
            "shear_direction", "excited_axes"} <= set(mt["array"])
    report = (out / "report.md").read_text()
    assert "## Module array" in report and "| right |" in report
    assert "array_shear_direction.png" in report
    torque = {"array_torque_time.png", "array_torque_scatter.png"}
    assert (torque <= names) == ("torque_rmse_nm" in mt) == (not press)
    assert ("| Tx | not observed" in report) == (not press)
    assert "Module array" in (out / "report.html").read_text()


def test_array_bag_without_the_gauge(run, assert_one_sentence, tmp_path, capsys):
    bag = write_array_bag(tmp_path / "bag", shear_signals(PROTOCOL, ArrayTruth()),
                          omit=("reference",))
    code, err = run([str(bag), "--out", str(tmp_path / "o")], capsys)
    assert_one_sentence(code, err, "/bench/gauge/wrench", "--reference-topic")


def test_array_bag_without_the_driver_wrench(run, assert_one_sentence, tmp_path, capsys):
    bag = write_array_bag(tmp_path / "bag", shear_signals(PROTOCOL, ArrayTruth()), "mcap",
                          omit=("estimate",))
    code, err = run([str(bag), "--out", str(tmp_path / "o"), "--prediction", "none"], capsys)
    assert_one_sentence(code, err, "module array", "4 modules", "/driver/wrench",
                        "--estimate-topic")


def test_driver_wrench_without_lateral_force(run, assert_one_sentence, tmp_path, capsys):
    signals = shear_signals(PROTOCOL, ArrayTruth())
    flat = signals.estimate_n.copy()
    flat[:, :2] = 0.0
    bag = write_array_bag(tmp_path / "bag", dataclasses.replace(signals, estimate_n=flat))
    code, err = run([str(bag), "--out", str(tmp_path / "o"), "--prediction", "none"], capsys)
    assert_one_sentence(code, err, "no lateral force", "/driver/wrench", "--estimate-topic")


def test_estimate_topic_of_the_wrong_type(run, assert_one_sentence, tmp_path, capsys):
    bag = write_array_bag(tmp_path / "bag", shear_signals(PROTOCOL, ArrayTruth()))
    code, err = run([str(bag), "--out", str(tmp_path / "o"), "--prediction", "none",
                     "--estimate-topic", "/bench/stage/joint_states"], capsys)
    assert_one_sentence(code, err, "JointState", "no field wrench.force.x", "--estimate-topic")


def test_array_topics_that_do_not_overlap(run, assert_one_sentence, tmp_path, capsys):
    signals = shear_signals(PROTOCOL, ArrayTruth())
    late = signals.estimate_n.copy()
    late[: late.shape[0] // 2] = np.nan  # the driver's wrench only in the second half ...
    outputs = signals.outputs_v.copy()
    outputs[late.shape[0] // 2 - 5:] = np.nan  # ... the modules only in the first
    bag = write_array_bag(tmp_path / "bag", dataclasses.replace(signals, estimate_n=late,
                                                                outputs_v=outputs))
    code, err = run([str(bag), "--out", str(tmp_path / "o"), "--prediction", "none"], capsys)
    assert_one_sentence(code, err, "do not overlap")


def test_reference_of_a_type_without_lateral_force(run, assert_one_sentence, tmp_path, capsys):
    """A one-axis gauge type (force.z only) on an array recording: no lateral reference."""
    store = writer_typestore()
    store.register({**get_types_from_msg("float64 z", "test_msgs/msg/ZForce"),
                    **get_types_from_msg("test_msgs/ZForce force", "test_msgs/msg/ZWrench"),
                    **get_types_from_msg("std_msgs/Header header\ntest_msgs/ZWrench wrench",
                                         "test_msgs/msg/ZWrenchStamped")})
    signals = shear_signals(dataclasses.replace(PROTOCOL, rate_hz=50.0), ArrayTruth())
    stamps = 1_700_000_000_000_000_000 + np.round(signals.t_s * 1e9).astype(np.int64)
    faces = signals.faces
    reading = {"output": signals.outputs_v[:, 0],
               **{f"outputs[{i}]": signals.outputs_v[:, i] for i in range(len(faces))}}
    wrench = {f"wrench.force.{a}": signals.estimate_n[:, j] for j, a in enumerate("xyz")}
    streams = [("/driver/reading", READING_TYPE, reading),
               ("/driver/wrench", WRENCH_TYPE, wrench),
               ("/bench/stage/joint_states", JOINT_TYPE,
                {f"position[{j}]": signals.stage_m[:, j] for j in range(3)})]
    with Writer(tmp_path / "bag", version=9) as writer:
        for topic, msgtype, values in streams:
            conn = writer.add_connection(topic, msgtype, typestore=store)
            for ts, row in zip(stamps.tolist(), serialize_many(store, msgtype, stamps, values,
                                                               faces, joints=3), strict=True):
                writer.write(conn, ts, row.tobytes())
        typ = "test_msgs/msg/ZWrenchStamped"
        T = store.types
        conn = writer.add_connection("/bench/gauge/wrench", typ, typestore=store)
        for ts, fz in zip(stamps.tolist(), signals.reference_n[:, 2], strict=True):
            header = T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](
                sec=ts // 10**9, nanosec=ts % 10**9), frame_id="gauge")
            msg = T[typ](header=header, wrench=T["test_msgs/msg/ZWrench"](
                force=T["test_msgs/msg/ZForce"](z=float(fz))))
            writer.write(conn, ts, bytes(store.serialize_cdr(msg, typ)))
    code, err = run([str(tmp_path / "bag"), "--out", str(tmp_path / "o"), "--prediction",
                     "none"], capsys)
    assert_one_sentence(code, err, "ZWrenchStamped", "no lateral force", "--reference-topic")


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(-0.5, 0.5), min_size=12, max_size=12),
       st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3),
       st.integers(0, 2**16))
def test_pure_fits_recover_any_linear_truth(s_flat, offset, seed):
    """Any S and any constant estimate offset, on forces exciting all three axes."""
    rng = np.random.default_rng(seed)
    force = rng.uniform(-2.0, 2.0, (200, 3)) * np.array([1.0, 1.5, 3.0])
    s = np.array(s_flat).reshape(4, 3)
    sens = arr.sensitivity_matrix(force @ s.T + 0.3, force, ("a", "b", "c", "d"))
    np.testing.assert_allclose(sens.matrix_v_per_n, s, atol=1e-9)
    np.testing.assert_allclose(sens.offset_v, 0.3, atol=1e-9)
    rmse, span = arr.force_errors(force + np.array(offset), force)
    np.testing.assert_allclose(rmse, np.abs(offset), rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(span, force.max(axis=0) - force.min(axis=0))
    np.testing.assert_allclose(arr.cross_talk(force + np.array(offset), force), np.eye(3),
                               atol=1e-9)
