"""One recording in, the paper's characterisation out: metrics plus what the plots need."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from . import metrics as m
from . import uncertainty as u
from .alignment import Aligned, align
from .array import analysis as arr
from .array.fit import ArrayFit, fit_array_recording
from .bag_reader import Notify, Progress, Recording, TopicSpec, read_recording
from .calibration_fit import Calibration, fit_calibration
from .errors import RateFitError, SegmentError, TopicError
from .prediction import Prediction
from .rate.evaluation import phase_table, table_dict
from .rate.fit import FitProgress, RateFit, fit_rate_calibration
from .rate.record import RateRecord, record_from_segmentation
from .segmentation import GAP_SHARE, Cycle, Segmentation, segment

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


UNCERTAINTY_NOTE = ("*_ci95 keys: half-width of the 95 % interval over the cycles (Student's "
                    "t; medians' standard error 1.2533 sd/sqrt(n)); null with one cycle: "
                    f"{u.ONE_CYCLE}. docs/analysis-metrics.md, Uncertainties.")

#: The reference speed's uncertainty keys (static_uncertainty), all null without a press.
UNCERTAINTY_KEYS = (
    "full_scale_ci95_n", "full_scale_output_ci95_v", "sensitivity_se_v_per_n",
    "sensitivity_ci95_v_per_n", "noise_ci95_v", "noise_runs", "resolution_ci95_n",
    "dynamic_range_ci95_db", "hysteresis_ci95_pct_fs", "hysteresis_cycles_pct_fs",
    "peak_output_cv_ci95_pct", "drift_ci95_pct", "peak_outputs_v")


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


@dataclass(frozen=True)
class _FullScale:
    """The reference speed's presses and their median peak: what every metric scales by."""

    ref_key: str
    ref_cycles: list[Cycle]
    peaks: np.ndarray  # (cycles, 2): peak output [V], peak force [N]
    output_v: float
    force_n: float


@dataclass(frozen=True)
class _StaticFigures:
    """The paper's single-speed figures at the reference speed."""

    sensitivity: m.LinearFit | None
    noise: m.Noise | None
    resolution_n: float | None
    dynamic_range_db: float | None
    hysteresis: m.Hysteresis | None
    repeatability: m.Repeatability
    #: 95 % intervals and standard errors (metrics.json keys, docs/analysis-metrics.md)
    uncertainty: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class _Calibrations:
    """The curves fitted from the recording and the one the force error is judged on."""

    fitted: Calibration | None
    static_reference: Calibration | None
    rate_fit: RateFit | None
    evaluated: Calibration | None
    metrics: dict[str, Any] | None

    @property
    def compared(self) -> Calibration | None:
        """The static curve a rate-aware one was compared with, phase by phase."""
        return (self.static_reference
                if self.metrics is not None and "by_speed_phase" in self.metrics else None)


def recording_notes(recording: Recording, aligned: Aligned, seg: Segmentation) -> list[str]:
    """What the reader should know before trusting the figures: a flipped gauge, presses
    left out, topics that lost messages."""
    notes = list(recording.notes)
    if aligned.force_flipped:
        notes.append("reference force was mostly negative; its sign was flipped so that "
                     "compression is positive.")
    if seg.skipped:
        notes.append(f"{seg.skipped} press(es) cut off by the recording's start or end, or "
                     "with too few samples, were left out.")
    return notes + gap_notes(recording, aligned, seg)


def full_scale(sig: m.Signals, seg: Segmentation) -> _FullScale:
    ref_key = seg.reference_key
    ref_cycles = [seg.cycles[i] for i in seg.speed_groups[ref_key]]
    peaks = np.array([m.peak_values(sig, c) for c in ref_cycles])
    return _FullScale(ref_key, ref_cycles, peaks, float(np.median(peaks[:, 0])),
                      float(np.median(peaks[:, 1])))


def _ci(values: Any, statistic: str = "mean") -> float | None:
    """Half-width of the 95 % interval over cycles (None for one cycle)."""
    return _num(u.spread(values, statistic).ci95)


def speed_table(sig: m.Signals, seg: Segmentation, rate_hz: float
                ) -> tuple[dict[str, Any], dict[str, float | None]]:
    """Each speed's sensitivity, peaks and phase lag, each with its 95 % interval over
    the speed's cycles: the paper's across-speed figure."""
    by_speed: dict[str, Any] = {}
    lags: dict[str, float | None] = {}
    for key, members in seg.speed_groups.items():
        group = [seg.cycles[i] for i in members]
        fit = m.sensitivity(sig, group)
        gpeaks = np.array([m.peak_values(sig, c) for c in group])
        per_cycle = m.phase_lags(sig, group, rate_hz)
        lag = u.spread(per_cycle, "median")
        lags[key] = lag.centre
        by_speed[key] = {
            "cycles": len(group),
            "loading_speed_mm_s": _num(float(np.median([c.speed_mm_s for c in group]))),
            "unloading_speed_mm_s": _num(float(np.median([c.unload_speed_mm_s
                                                          for c in group]))),
            "sensitivity_v_per_n": _num(fit.slope) if fit else None,
            "sensitivity_se_v_per_n": _num(fit.slope_se) if fit else None,
            "sensitivity_ci95_v_per_n": _ci(m.sensitivities(sig, group)),
            "sensitivity_r2": _num(fit.r2) if fit else None,
            "peak_indentation_m": _num(float(np.median([c.peak_indentation_m
                                                        for c in group]))),
            "peak_force_n": _num(float(np.median(gpeaks[:, 1]))),
            "peak_force_ci95_n": _ci(gpeaks[:, 1], "median"),
            "peak_output_v": _num(float(np.median(gpeaks[:, 0]))),
            "peak_output_ci95_v": _ci(gpeaks[:, 0], "median"),
            "phase_lag_s": _num(lags[key]),
            "phase_lag_sem_s": _num(lag.se),
            "phase_lag_ci95_s": _num(lag.ci95),
            "phase_lag_cycles": lag.cycles,
            "phase_lags_s": [_num(x) for x in lag.values],
        }
    return by_speed, lags


def static_figures(sig: m.Signals, seg: Segmentation, scale: _FullScale,
                   noise_window: int) -> _StaticFigures:
    sens = m.sensitivity(sig, scale.ref_cycles)
    noise = m.noise(sig, seg, noise_window)
    resolution = (noise.sigma_v / sens.slope
                  if noise and sens and sens.slope > 0 and noise.sigma_v > 0 else None)
    dyn = (20 * math.log10(scale.force_n / resolution)
           if resolution and scale.force_n > 0 else None)
    hyst = m.hysteresis(sig, scale.ref_cycles, scale.force_n, scale.output_v)
    rep = m.repeatability(scale.peaks[:, 0])
    figures = _StaticFigures(sens, noise, resolution, dyn, hyst, rep)
    return replace(figures, uncertainty=static_uncertainty(sig, scale, figures))


def static_uncertainty(sig: m.Signals, scale: _FullScale, figures: _StaticFigures
                       ) -> dict[str, Any]:
    """How sure each reference-speed figure is: 95 % intervals over the cycles, the
    sensitivity fit's standard error, and resolution and dynamic range propagated from
    the noise over rests, the sensitivity and the full scale (first order)."""
    sens, noise, rep = figures.sensitivity, figures.noise, figures.repeatability
    cycles = scale.ref_cycles
    force, output = u.spread(scale.peaks[:, 1], "median"), u.spread(scale.peaks[:, 0], "median")
    slopes = u.spread(m.sensitivities(sig, cycles))
    noise_runs = u.spread(noise.runs_v if noise else ())
    hyst = u.spread(m.hysteresis_per_cycle(sig, cycles, scale.force_n, scale.output_v)
                    if figures.hysteresis else ())
    # the sensitivity's error from press to press where there are presses to compare,
    # else its fit's: the resolution moves with whichever is known
    sens_se = slopes.se if slopes.se is not None else (sens.slope_se if sens else None)
    rel_sens = u.relative_se(sens.slope if sens else None, sens_se)
    rel_noise = u.relative_se(noise.sigma_v if noise else None, noise_runs.se)
    res_se = (u.quotient_se(figures.resolution_n, rel_noise, rel_sens)
              if figures.resolution_n else None)
    dyn_se = (u.decibel_se(u.relative_se(scale.force_n, force.se),
                           u.relative_se(figures.resolution_n, res_se))
              if figures.dynamic_range_db is not None else None)
    cv = u.cv_interval(rep.cv_pct, rep.peaks_v.size)
    return {
        "full_scale_ci95_n": _num(force.ci95),
        "full_scale_output_ci95_v": _num(output.ci95),
        "sensitivity_se_v_per_n": _num(sens.slope_se) if sens else None,
        "sensitivity_ci95_v_per_n": _num(slopes.ci95),
        "noise_ci95_v": _num(noise_runs.ci95),
        "noise_runs": noise_runs.cycles,
        "resolution_ci95_n": _num(u.normal_ci95(res_se)),
        "dynamic_range_ci95_db": _num(u.normal_ci95(dyn_se)),
        "hysteresis_ci95_pct_fs": _num(hyst.ci95),
        "hysteresis_cycles_pct_fs": [_num(x) for x in hyst.values],
        "peak_output_cv_ci95_pct": [_num(cv[0]), _num(cv[1])] if cv else None,
        "drift_ci95_pct": _num(u.drift_ci95(rep.peaks_v, rep.drift_cycles)
                               if rep.drift_pct is not None else None),
        "peak_outputs_v": [_num(float(x)) for x in rep.peaks_v],
    }


def static_reference(recording: Recording, sig: m.Signals, scale: _FullScale
                     ) -> Calibration:
    """Today's static curve: the reference speed's ramps."""
    idx = np.concatenate([m.ramp_indices(scale.ref_cycles, "load"),
                          m.ramp_indices(scale.ref_cycles, "unload")])
    curve = fit_calibration(sig.output_v[idx], sig.force_n[idx],
                            source=f"tactile-sensor analyze {recording.path}")
    curve.fit.update({"speed_mm_s": float(scale.ref_key), "cycles": len(scale.ref_cycles),
                      "output_baseline_v": sig.output_baseline_v,
                      "force_baseline_n": sig.force_baseline_n})
    return curve


def fit_rates(recording: Recording, sig: m.Signals, seg: Segmentation, record: RateRecord,
              options: Options, notes: list[str]) -> RateFit | None:
    """The rate terms, where the recording has two speeds or more; a failed fit is a note
    and the static curve stands."""
    if len(seg.speed_groups) < 2:
        return None
    try:
        return fit_rate_calibration(record, source=f"tactile-sensor analyze {recording.path}",
                                    progress=options.fit_progress)
    except RateFitError as err:
        notes.append(f"no rate terms fitted: {err} The static curve at "
                     f"{seg.reference_key} mm/s was written instead.")
        return None


def rate_aware_curve(rate_fit: RateFit, sig: m.Signals) -> Calibration:
    rate_cal = rate_fit.calibration
    return Calibration(np.asarray(rate_cal.static.output_v),
                       np.asarray(rate_cal.static.force_n), rate_cal.source,
                       {**rate_fit.metadata(),
                        "output_baseline_v": sig.output_baseline_v,
                        "force_baseline_n": sig.force_baseline_n},
                       rate_cal)


def calibration_error(evaluated: Calibration, options: Options, sig: m.Signals,
                      seg: Segmentation, scale: _FullScale, record: RateRecord,
                      static_ref: Calibration | None, rate_fit: RateFit | None
                      ) -> dict[str, Any]:
    """The force error of the calibration judged (given or fitted), per speed, and per
    phase against the static curve when it has rate terms."""
    history = evaluated.force_history(sig.t_s, sig.output_v)
    per_speed = {}
    for key, members in seg.speed_groups.items():
        group = [seg.cycles[i] for i in members]
        idx = np.concatenate([m.ramp_indices(group, "load"), m.ramp_indices(group, "unload")])
        per_speed[key] = _err_dict(m.estimation_error(
            history[idx], sig.force_n[idx], scale.force_n))
    rate = evaluated.rate
    out: dict[str, Any] = {
        "source": evaluated.source, "in_sample": options.calibration is None,
        "by_speed": per_speed,
        "rate_terms": ([{"g": t.g, "tau_s": t.tau_s} for t in rate.terms]
                       if rate is not None else None),
        "play": rate.play.to_dict() if rate is not None and rate.play is not None else None}
    if rate is not None and static_ref is not None:
        out["by_speed_phase"] = table_dict(phase_table(record, static_ref, rate))
        out["static_reference"] = (
            f"a static curve fitted on this recording's {scale.ref_key} mm/s ramps")
    if rate_fit is not None:
        out["held_out_rmse_n"] = rate_fit.folds.held_out_rmse_n
        out["static_held_out_rmse_n"] = rate_fit.folds.static_rmse_n
    return out


def calibrate(recording: Recording, sig: m.Signals, seg: Segmentation, scale: _FullScale,
              options: Options, notes: list[str]) -> _Calibrations:
    """Fit the curves asked for (static, then rate-aware) and judge the one in use."""
    static_ref = None
    if options.fit_calibration or (options.calibration is not None
                                   and options.calibration.rate is not None):
        static_ref = static_reference(recording, sig, scale)
    record = record_from_segmentation(sig.t_s, sig.output_v, sig.force_n, seg)
    fitted, rate_fit = None, None
    if options.fit_calibration:
        fitted = static_ref
        rate_fit = fit_rates(recording, sig, seg, record, options, notes)
        if rate_fit is not None and static_ref is not None:
            notes.extend(rate_fit.notes)
            fitted = rate_aware_curve(rate_fit, sig)
    evaluated = options.calibration or fitted
    cal_metrics = (calibration_error(evaluated, options, sig, seg, scale, record, static_ref,
                                     rate_fit) if evaluated is not None else None)
    return _Calibrations(fitted, static_ref, rate_fit, evaluated, cal_metrics)


def compare_with_prediction(sig: m.Signals, scale: _FullScale, options: Options,
                            notes: list[str]
                            ) -> tuple[m.PredictionComparison | None, dict[str, Any] | None]:
    if options.prediction is None:
        notes.append(f"model prediction: {options.prediction_note}.")
        return None, None
    pred_cmp = m.compare_prediction(sig, scale.ref_cycles, options.prediction.indentation_m,
                                    options.prediction.output_v, scale.output_v)
    if pred_cmp is None:
        notes.append("the prediction does not overlap the measured indentation range.")
        return None, None
    return pred_cmp, {"source": options.prediction.source, "rmse_v": _num(pred_cmp.rmse_v),
                      "max_v": _num(pred_cmp.max_v), "rmse_pct_fs": _num(pred_cmp.rmse_pct_fs)}


def characterisation_metrics(recording: Recording, aligned: Aligned, sig: m.Signals,
                             seg: Segmentation, scale: _FullScale, figures: _StaticFigures,
                             speeds: tuple[dict[str, Any], dict[str, float | None]],
                             cal_metrics: dict[str, Any] | None,
                             pred_metrics: dict[str, Any] | None, notes: list[str]
                             ) -> dict[str, Any]:
    """The metrics file's content (docs/analysis-metrics.md)."""
    by_speed, lags = speeds
    sens, noise, hyst, rep = (figures.sensitivity, figures.noise, figures.hysteresis,
                              figures.repeatability)
    return {
        "schema": SCHEMA, "version": 1,
        "bag": str(recording.path), "storage": recording.storage,
        "topics": {r: recording.series[r].topic for r in ROLES},
        "stamps": {r: recording.series[r].stamp_source for r in ROLES},
        "samples": int(aligned.t_s.size), "duration_s": _num(float(aligned.t_s[-1])),
        "sample_rate_hz": _num(aligned.rate_hz),
        "cycles": len(seg.cycles), "reference_speed_mm_s": float(scale.ref_key),
        "full_scale_n": _num(scale.force_n), "full_scale_output_v": _num(scale.output_v),
        "output_baseline_v": _num(sig.output_baseline_v),
        "force_baseline_n": _num(sig.force_baseline_n),
        "sensitivity_v_per_n": _num(sens.slope) if sens else None,
        "sensitivity_r2": _num(sens.r2) if sens else None,
        "noise_v": _num(noise.sigma_v) if noise else None,
        "noise_estimate": noise.source if noise else None,
        "resolution_n": _num(figures.resolution_n),
        "dynamic_range_db": _num(figures.dynamic_range_db),
        "hysteresis_pct_fs": _num(hyst.pct_fs) if hyst else None,
        "peak_output_cv_pct": _num(rep.cv_pct),
        "drift_pct": _num(rep.drift_pct),
        "drift_cycles_compared": rep.drift_cycles,
        "phase_lag_s": {k: _num(v) for k, v in lags.items()},
        "by_speed": by_speed,
        **figures.uncertainty,
        "uncertainty": UNCERTAINTY_NOTE,
        "calibration_error": cal_metrics,
        "prediction": pred_metrics,
        "paper": PAPER,
        "notes": notes,
    }


def characterise(recording: Recording, options: Options) -> Characterisation:
    """The paper's characterisation as a pipeline: align, find the presses, take the
    baselines, then the figures, the calibrations and the prediction's fit."""
    aligned = align(recording)
    seg = segment(aligned, options.reference_speed_mm_s, recording.series["position"].topic)
    sig = m.baseline(aligned, seg)
    notes = recording_notes(recording, aligned, seg)
    scale = full_scale(sig, seg)
    speeds = speed_table(sig, seg, aligned.rate_hz)
    figures = static_figures(sig, seg, scale, options.noise_window)
    cal = calibrate(recording, sig, seg, scale, options, notes)
    pred_cmp, pred_metrics = compare_with_prediction(sig, scale, options, notes)
    metrics = characterisation_metrics(recording, aligned, sig, seg, scale, figures, speeds,
                                       cal.metrics, pred_metrics, notes)
    return Characterisation(metrics, recording, aligned, seg, sig, figures.hysteresis,
                            figures.repeatability, pred_cmp, cal.fitted, cal.evaluated,
                            speeds[1], cal.rate_fit, cal.compared)


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
        **dict.fromkeys(UNCERTAINTY_KEYS), "uncertainty": UNCERTAINTY_NOTE,
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
