"""One recording in, the paper's characterisation out: metrics plus what the plots need."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from . import metrics as m
from .alignment import Aligned, align
from .array import analysis as arr
from .array.fit import ArrayFit, fit_array_recording
from .bag_reader import Notify, Progress, Recording, TopicSpec, read_recording
from .calibration_fit import Calibration, fit_calibration
from .errors import RateFitError, SegmentError, TopicError
from .prediction import Prediction
from .rate.evaluation import phase_table, table_dict
from .rate.fit import FitProgress, RateFit, fit_rate_calibration
from .rate.record import record_from_segmentation
from .segmentation import GAP_SHARE, Segmentation, segment

SCHEMA = "tactile_sensor/analysis-metrics"
ROLES = ("reading", "reference", "position")  # the single-module analysis' topics
PAPER: dict[str, Any] = {
    "sensitivity_v_per_n": 0.07,
    "dynamic_range_db": 31.49,
    "full_scale_n": 7.0,  # "approximately 7 N" at 3 mm, 1 mm/s
    "phase_lag_s": {"10.0": 0.005, "1.0": 0.062, "0.1": 0.706},
    "hysteresis_pct_fs": None,  # described as low, not quantified
    "peak_output_cv_pct": None,  # "no change was observed in the maximum output"
    "drift_pct": None,
}


@dataclass(frozen=True)
class Topics:
    reading: str = "/driver/reading"
    reference: str = "/bench/gauge/wrench"
    position: str = "/bench/stage/joint_states"
    estimate: str = "/driver/wrench"  # the driver's force estimate; read when present

    def specs(self) -> list[TopicSpec]:
        """Today's three topics, plus what an array recording adds where the bag has it:
        every module's output and face, the gauge's lateral force and torque, the driver's
        wrench."""
        return [
            TopicSpec("reading", self.reading, {"output_v": "output"}, "--reading-topic",
                      "TactileReading", sequences={"outputs_v": "outputs"},
                      labels={"faces": "faces"}),
            TopicSpec("reference", self.reference, {"force_n": "wrench.force.z"},
                      "--reference-topic", "WrenchStamped",
                      optional={"force_x_n": "wrench.force.x", "force_y_n": "wrench.force.y",
                                **arr.TORQUE_FIELDS}),
            TopicSpec("position", self.position, {"indentation_m": "position[0]"},
                      "--position-topic", "JointState"),
            TopicSpec("estimate", self.estimate,
                      {"force_x_n": "wrench.force.x", "force_y_n": "wrench.force.y",
                       "force_n": "wrench.force.z"}, "--estimate-topic", "WrenchStamped",
                      required=False, optional=dict(arr.TORQUE_FIELDS)),
        ]


@dataclass(frozen=True)
class Options:
    topics: Topics = field(default_factory=Topics)
    reference_speed_mm_s: float = 1.0
    noise_window: int = 9
    calibration: Calibration | None = None
    fit_calibration: bool = False
    prediction: Prediction | None = None
    prediction_note: str = "no prediction requested"
    fit_progress: FitProgress | None = None  # hears of each rate fit (they take a minute)


@dataclass(frozen=True)
class Characterisation:
    """Metrics (JSON-ready) and the intermediate results plots and the report draw."""

    metrics: dict[str, Any]
    recording: Recording
    aligned: Aligned
    segmentation: Segmentation
    signals: m.Signals
    hysteresis: m.Hysteresis | None
    repeatability: m.Repeatability
    prediction: m.PredictionComparison | None
    fitted: Calibration | None
    evaluated: Calibration | None
    lags_s: dict[str, float | None]
    rate_fit: RateFit | None = None
    #: The static curve the rate-aware one is compared with (by_speed_phase), if any.
    static_reference: Calibration | None = None


def _num(x: float | None, digits: int = 6) -> float | None:
    if x is None or not math.isfinite(x):
        return None
    return float(f"{x:.{digits}g}")


def _err_dict(e: m.EstimationError | None) -> dict[str, Any] | None:
    if e is None:
        return None
    return {"rmse_n": _num(e.rmse_n), "max_n": _num(e.max_n),
            "rmse_pct_fs": _num(e.rmse_pct_fs), "max_pct_fs": _num(e.max_pct_fs),
            "samples": e.samples}


def analyse_bag(bag: str, options: Options, progress: Progress | None = None,
                notify: Notify | None = None) -> Characterisation:
    recording = read_recording(bag, options.topics.specs(), progress, notify)
    return characterise(recording, options)


def gap_notes(recording: Recording, aligned: Aligned, seg: Segmentation) -> list[str]:
    """Say where a topic lost messages: values there are interpolated, and a press inside
    a gap of the stage topic cannot be seen at all (so the cycle count is short)."""
    notes = []
    windows = [(aligned.t_s[c.window[0]], aligned.t_s[c.window[1] - 1]) for c in seg.cycles]
    for role, gaps in aligned.gaps_s.items():
        lengths = [b - a for a, b in gaps]
        hit = sum(any(a < w1 and b > w0 for a, b in gaps) for w0, w1 in windows)
        notes.append(f"topic {recording.series[role].topic} has {len(gaps)} gap(s) without "
                     f"messages (longest {max(lengths):.3f} s, {sum(lengths):.3f} s in all; "
                     f"the recorder or publisher was starved); {hit} analysed cycle(s) "
                     "overlap them (values interpolated there)"
                     + ("; a press entirely inside one cannot be found." if role == "position"
                        else "."))
    if seg.in_position_gaps:
        notes.append(f"{seg.in_position_gaps} press(es) were left out because messages are "
                     "missing in them (any on the stage topic, or more than "
                     f"{GAP_SHARE:.0%} of the press on the output or force topic).")
    return notes


def characterise(recording: Recording, options: Options) -> Characterisation:
    aligned = align(recording)
    seg = segment(aligned, options.reference_speed_mm_s, recording.series["position"].topic)
    sig = m.baseline(aligned, seg)
    cycles = seg.cycles
    notes = list(recording.notes)
    if aligned.force_flipped:
        notes.append("reference force was mostly negative; its sign was flipped so that "
                     "compression is positive.")
    if seg.skipped:
        notes.append(f"{seg.skipped} press(es) cut off by the recording's start or end, or "
                     "with too few samples, were left out.")
    notes += gap_notes(recording, aligned, seg)
    ref_key = seg.reference_key
    ref_cycles = [cycles[i] for i in seg.speed_groups[ref_key]]
    peaks = np.array([m.peak_values(sig, c) for c in ref_cycles])
    full_scale_v, full_scale_n = (float(np.median(peaks[:, 0])), float(np.median(peaks[:, 1])))

    by_speed: dict[str, Any] = {}
    lags: dict[str, float | None] = {}
    for key, members in seg.speed_groups.items():
        group = [cycles[i] for i in members]
        fit = m.sensitivity(sig, group)
        gpeaks = np.array([m.peak_values(sig, c) for c in group])
        per_cycle = m.phase_lags(sig, group, aligned.rate_hz)
        lags[key] = float(np.median(per_cycle)) if per_cycle else None
        by_speed[key] = {
            "cycles": len(group),
            "loading_speed_mm_s": _num(float(np.median([c.speed_mm_s for c in group]))),
            "unloading_speed_mm_s": _num(float(np.median([c.unload_speed_mm_s
                                                          for c in group]))),
            "sensitivity_v_per_n": _num(fit.slope) if fit else None,
            "sensitivity_r2": _num(fit.r2) if fit else None,
            "peak_force_n": _num(float(np.median(gpeaks[:, 1]))),
            "peak_output_v": _num(float(np.median(gpeaks[:, 0]))),
            "phase_lag_s": _num(lags[key]),
            "phase_lag_sem_s": _num(m.lag_standard_error(per_cycle)),
        }

    sens = m.sensitivity(sig, ref_cycles)
    noise = m.noise(sig, seg, options.noise_window)
    resolution = (noise.sigma_v / sens.slope
                  if noise and sens and sens.slope > 0 and noise.sigma_v > 0 else None)
    dyn = (20 * math.log10(full_scale_n / resolution)
           if resolution and full_scale_n > 0 else None)
    hyst = m.hysteresis(sig, ref_cycles, full_scale_n, full_scale_v)
    rep = m.repeatability(peaks[:, 0])

    fitted = None
    static_ref = None  # today's static curve: the reference speed's ramps
    if options.fit_calibration or (options.calibration is not None
                                   and options.calibration.rate is not None):
        idx = np.concatenate([m.ramp_indices(ref_cycles, "load"),
                              m.ramp_indices(ref_cycles, "unload")])
        static_ref = fit_calibration(sig.output_v[idx], sig.force_n[idx],
                                     source=f"tactile-sensor analyze {recording.path}")
        static_ref.fit.update({"speed_mm_s": float(ref_key), "cycles": len(ref_cycles),
                               "output_baseline_v": sig.output_baseline_v,
                               "force_baseline_n": sig.force_baseline_n})
    rate_fit = None
    record = record_from_segmentation(sig.t_s, sig.output_v, sig.force_n, seg)
    if options.fit_calibration:
        fitted = static_ref
        if len(seg.speed_groups) >= 2:
            try:
                rate_fit = fit_rate_calibration(
                    record, source=f"tactile-sensor analyze {recording.path}",
                    progress=options.fit_progress)
            except RateFitError as err:
                notes.append(f"no rate terms fitted: {err} The static curve at "
                             f"{ref_key} mm/s was written instead.")
        if rate_fit is not None and static_ref is not None:
            rate_cal = rate_fit.calibration
            notes.extend(rate_fit.notes)
            fitted = Calibration(np.asarray(rate_cal.static.output_v),
                                 np.asarray(rate_cal.static.force_n), rate_cal.source,
                                 {**rate_fit.metadata(),
                                  "output_baseline_v": sig.output_baseline_v,
                                  "force_baseline_n": sig.force_baseline_n},
                                 rate_cal)
    evaluated = options.calibration or fitted
    cal_metrics = None
    if evaluated is not None:
        history = evaluated.force_history(sig.t_s, sig.output_v)
        per_speed = {}
        for key, members in seg.speed_groups.items():
            group = [cycles[i] for i in members]
            idx = np.concatenate([m.ramp_indices(group, "load"),
                                  m.ramp_indices(group, "unload")])
            per_speed[key] = _err_dict(m.estimation_error(
                history[idx], sig.force_n[idx], full_scale_n))
        cal_metrics = {"source": evaluated.source,
                       "in_sample": options.calibration is None, "by_speed": per_speed,
                       "rate_terms": ([{"g": t.g, "tau_s": t.tau_s}
                                       for t in evaluated.rate.terms]
                                      if evaluated.rate is not None else None),
                       "play": (evaluated.rate.play.to_dict()
                                if evaluated.rate is not None
                                and evaluated.rate.play is not None else None)}
        if evaluated.rate is not None and static_ref is not None:
            cal_metrics["by_speed_phase"] = table_dict(
                phase_table(record, static_ref, evaluated.rate))
            cal_metrics["static_reference"] = (
                f"a static curve fitted on this recording's {ref_key} mm/s ramps")
        if rate_fit is not None:
            cal_metrics["held_out_rmse_n"] = rate_fit.folds.held_out_rmse_n
            cal_metrics["static_held_out_rmse_n"] = rate_fit.folds.static_rmse_n

    pred_cmp = None
    pred_metrics = None
    if options.prediction is not None:
        pred_cmp = m.compare_prediction(sig, ref_cycles, options.prediction.indentation_m,
                                        options.prediction.output_v, full_scale_v)
        if pred_cmp is not None:
            pred_metrics = {"source": options.prediction.source, "rmse_v": _num(pred_cmp.rmse_v),
                            "max_v": _num(pred_cmp.max_v),
                            "rmse_pct_fs": _num(pred_cmp.rmse_pct_fs)}
        else:
            notes.append("the prediction does not overlap the measured indentation range.")
    else:
        notes.append(f"model prediction: {options.prediction_note}.")

    metrics: dict[str, Any] = {
        "schema": SCHEMA, "version": 1,
        "bag": str(recording.path), "storage": recording.storage,
        "topics": {r: recording.series[r].topic for r in ROLES},
        "stamps": {r: recording.series[r].stamp_source for r in ROLES},
        "samples": int(aligned.t_s.size), "duration_s": _num(float(aligned.t_s[-1])),
        "sample_rate_hz": _num(aligned.rate_hz),
        "cycles": len(cycles), "reference_speed_mm_s": float(ref_key),
        "full_scale_n": _num(full_scale_n), "full_scale_output_v": _num(full_scale_v),
        "output_baseline_v": _num(sig.output_baseline_v),
        "force_baseline_n": _num(sig.force_baseline_n),
        "sensitivity_v_per_n": _num(sens.slope) if sens else None,
        "sensitivity_r2": _num(sens.r2) if sens else None,
        "noise_v": _num(noise.sigma_v) if noise else None,
        "noise_estimate": noise.source if noise else None,
        "resolution_n": _num(resolution),
        "dynamic_range_db": _num(dyn),
        "hysteresis_pct_fs": _num(hyst.pct_fs) if hyst else None,
        "peak_output_cv_pct": _num(rep.cv_pct),
        "drift_pct": _num(rep.drift_pct),
        "drift_cycles_compared": rep.drift_cycles,
        "phase_lag_s": {k: _num(v) for k, v in lags.items()},
        "by_speed": by_speed,
        "calibration_error": cal_metrics,
        "prediction": pred_metrics,
        "paper": PAPER,
        "notes": notes,
    }
    compared = (static_ref if cal_metrics is not None and "by_speed_phase" in cal_metrics
                else None)
    return Characterisation(metrics, recording, aligned, seg, sig, hyst, rep, pred_cmp, fitted,
                            evaluated, lags, rate_fit, compared)


@dataclass(frozen=True)
class Analysis:
    """What ``tactile-sensor analyze`` writes: the metrics, the single-module
    characterisation (None when an array recording cannot be segmented into presses) and
    the array analysis (None for a single module)."""

    metrics: dict[str, Any]
    single: Characterisation | None
    array: arr.ArrayAnalysis | None
    #: The array calibration fitted from the recording (``--fit-calibration`` on an array)
    array_fit: ArrayFit | None = None

    @property
    def fitted(self) -> Calibration | None:
        return self.single.fitted if self.single is not None else None


def unavailable_metrics(recording: Recording, note: str) -> dict[str, Any]:
    """Today's metric keys, all null: the paper's characterisation could not be made (an
    array recording without a usable press); the array's metrics are added beside them."""
    return {
        "schema": SCHEMA, "version": 1,
        "bag": str(recording.path), "storage": recording.storage,
        "topics": {r: recording.series[r].topic for r in ROLES},
        "stamps": {r: recording.series[r].stamp_source for r in ROLES},
        "samples": None, "duration_s": None, "sample_rate_hz": None,
        "cycles": 0, "reference_speed_mm_s": None,
        "full_scale_n": None, "full_scale_output_v": None,
        "output_baseline_v": None, "force_baseline_n": None,
        "sensitivity_v_per_n": None, "sensitivity_r2": None,
        "noise_v": None, "noise_estimate": None, "resolution_n": None,
        "dynamic_range_db": None, "hysteresis_pct_fs": None,
        "peak_output_cv_pct": None, "drift_pct": None, "drift_cycles_compared": None,
        "phase_lag_s": {}, "by_speed": {},
        "calibration_error": None, "prediction": None,
        "paper": PAPER, "notes": [*recording.notes, note],
    }


def analyse(bag: str, options: Options, progress: Progress | None = None,
            notify: Notify | None = None) -> Analysis:
    """Single-module characterisation as always; on an array recording (detected from the
    data, ``array.detect``) the array's metrics too, and the paper's metrics where the
    recording has presses to give them."""
    recording = read_recording(bag, options.topics.specs(), progress, notify)
    reason = arr.detect(recording)
    if reason is None:
        single = characterise(recording, options)
        return Analysis(single.metrics, single, None)
    array = arr.analyse_array(recording, reason)
    try:  # the calibration fitted is the array's (below), not the first module's curve
        single = characterise(recording, replace(options, fit_calibration=False))
        metrics = dict(single.metrics)
    except (SegmentError, TopicError) as err:
        single = None
        metrics = unavailable_metrics(
            recording, "the paper's single-module characterisation does not apply to this "
            f"recording ({str(err).rstrip('.')}); only the array's metrics are given.")
    metrics.update(array.metrics)
    metrics["notes"] = list(metrics["notes"]) + array.notes
    fitted = None
    if options.fit_calibration:
        fitted = fit_array_recording(recording, f"tactile-sensor analyze {recording.path}")
        metrics["array_calibration_fit"] = fitted.metrics
    return Analysis(metrics, single, array, fitted)
