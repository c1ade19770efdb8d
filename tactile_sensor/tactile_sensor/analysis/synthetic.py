"""Synthetic press recordings with a ground truth chosen by the caller.

Why: the analysis must be shown to recover known sensitivity, lag, hysteresis, noise,
repeatability and drift from real rosbag2 files in both storage formats. The model here
is deliberately simple and independent of the analysis code: a trapezoidal indentation
d(t) at each speed, force F = F_max (d/d_max)^p scaled by a rate factor, and a module
output that follows the indentation (as the paper reports) with a per-speed lag,
an unloading-only hysteresis bump, a per-cycle gain, Gaussian noise and an offset.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore
from rosbags.typesys.store import Typestore

from .cdr_columns import walk
from .message_types import interface_types

READING_TYPE = "tactile_sensor_interfaces/msg/TactileReading"
WRENCH_TYPE = "geometry_msgs/msg/WrenchStamped"
JOINT_TYPE = "sensor_msgs/msg/JointState"
PAPER_LAGS_S: Mapping[float, float] = {10.0: 0.005, 1.0: 0.062, 0.1: 0.706}


@dataclass(frozen=True)
class PressProtocol:
    """The stage's motion: speeds in order, cycles at each, depth, hold and rest times."""

    speeds_mm_s: tuple[float, ...] = (1.0,)
    cycles: tuple[int, ...] = (10,)
    depth_m: float = 3e-3
    hold_s: float = 1.0
    rest_s: float = 1.0
    rate_hz: float = 1000.0


@dataclass(frozen=True)
class SensorTruth:
    """Ground truth of the synthetic sensor (paper-like defaults)."""

    sensitivity_v_per_n: float = 0.07
    force_at_depth_n: float = 7.0
    exponent: float = 1.2
    lag_s: Mapping[float, float] = field(default_factory=lambda: dict(PAPER_LAGS_S))
    hysteresis_frac: float = 0.02  # unloading bump, fraction of output full scale at mid force
    noise_v: float = 0.0392  # raw output noise; /3 after a 9-point mean -> ~31.5 dB
    force_noise_n: float = 0.0
    baseline_v: float = 0.02
    rate_gain_per_decade: float = 0.1  # force rises 10 % per decade of speed above 1 mm/s
    cycle_gain_cv: float = 0.0
    drift_frac: float = 0.0  # output gain change from first to last cycle

    def elastic_force_n(self, indentation_m: np.ndarray, depth_m: float) -> np.ndarray:
        x = np.clip(indentation_m / depth_m, 0.0, None)
        return self.force_at_depth_n * x ** self.exponent

    def rate_factor(self, speed_mm_s: float) -> float:
        return 1.0 + self.rate_gain_per_decade * np.log10(speed_mm_s)


@dataclass(frozen=True)
class PressSignals:
    """Sampled signals and the per-cycle truth behind them."""

    t_s: np.ndarray
    indentation_m: np.ndarray
    force_n: np.ndarray
    output_v: np.ndarray
    cycle_speed_mm_s: np.ndarray  # one per cycle
    cycle_gain: np.ndarray  # one per cycle


def press_signals(protocol: PressProtocol, truth: SensorTruth, seed: int = 0) -> PressSignals:
    """Indentation, reference force and module output sampled at protocol.rate_hz."""
    rng = np.random.default_rng(seed)
    dt = 1.0 / protocol.rate_hz
    speeds = [v for v, n in zip(protocol.speeds_mm_s, protocol.cycles, strict=True)
              for _ in range(n)]
    n_cycles = len(speeds)
    gains = 1.0 + truth.cycle_gain_cv * rng.standard_normal(n_cycles)
    if n_cycles > 1:
        gains *= 1.0 + truth.drift_frac * np.arange(n_cycles) / (n_cycles - 1)
    depth = protocol.depth_m
    t_parts, d_parts, f_parts, o_parts = [], [], [], []
    t0 = 0.0
    for c, v in enumerate(speeds):
        ramp = depth / (v * 1e-3)
        knots_t = np.array([0, protocol.rest_s, protocol.rest_s + ramp,
                            protocol.rest_s + ramp + protocol.hold_s,
                            protocol.rest_s + 2 * ramp + protocol.hold_s])
        knots_d = np.array([0.0, 0.0, depth, depth, 0.0])
        n = round(knots_t[-1] / dt)
        t = np.arange(n) * dt
        d = np.interp(t, knots_t, knots_d)
        lag = float(truth.lag_s.get(v, 0.0))
        d_late = np.interp(t - lag, knots_t, knots_d)
        f_el = truth.elastic_force_n(d, depth)
        force = f_el * truth.rate_factor(v)
        late = truth.elastic_force_n(d_late, depth)
        fs_out = truth.sensitivity_v_per_n * truth.force_at_depth_n
        x = late / truth.force_at_depth_n
        unloading = (t - lag > knots_t[3]) & (t - lag < knots_t[4])
        bump = np.where(unloading, truth.hysteresis_frac * fs_out * 4 * x * (1 - x), 0.0)
        out = gains[c] * (truth.sensitivity_v_per_n * late + bump)
        t_parts.append(t0 + t)
        d_parts.append(d)
        f_parts.append(force)
        o_parts.append(out)
        t0 += n * dt
    t_all = np.concatenate(t_parts)
    force_all = np.concatenate(f_parts) + truth.force_noise_n * rng.standard_normal(t_all.size)
    out_all = (np.concatenate(o_parts) + truth.baseline_v
               + truth.noise_v * rng.standard_normal(t_all.size))
    return PressSignals(t_s=t_all, indentation_m=np.concatenate(d_parts), force_n=force_all,
                        output_v=out_all, cycle_speed_mm_s=np.array(speeds, dtype=float),
                        cycle_gain=gains)


def writer_typestore() -> Typestore:
    """ROS 2 Kilted types plus ours, for writing bags."""
    store = get_typestore(Stores.ROS2_KILTED)
    store.register(interface_types())
    return store


def _templates(store: Typestore, faces: Sequence[str] = (), joints: int = 1
               ) -> dict[str, tuple[bytes, dict[str, tuple[int, str]]]]:
    """One serialized message per type and where its stamp and value fields sit in it.

    ``faces``: a module array's reading (faces, voltages[i], outputs[i] filled; empty for
    one module, as the driver sends it); ``joints``: positions in the stage's JointState.
    """
    T = store.types
    header = T["std_msgs/msg/Header"]
    time = T["builtin_interfaces/msg/Time"]
    vec = T["geometry_msgs/msg/Vector3"]
    msgs = {
        READING_TYPE: (T[READING_TYPE](header=header(stamp=time(sec=0, nanosec=0),
                                                     frame_id="tactile"),
                                       voltage=0.0, output=0.0, force=0.0, contact=False,
                                       faces=list(faces), voltages=np.zeros(len(faces)),
                                       outputs=np.zeros(len(faces))),
                       ["voltage", "output", "force", "contact",
                        *(f"{a}[{i}]" for a in ("voltages", "outputs")
                          for i in range(len(faces)))]),
        WRENCH_TYPE: (T[WRENCH_TYPE](header=header(stamp=time(sec=0, nanosec=0),
                                                   frame_id="gauge"),
                                     wrench=T["geometry_msgs/msg/Wrench"](
                                         force=vec(x=0.0, y=0.0, z=0.0),
                                         torque=vec(x=0.0, y=0.0, z=0.0))),
                      [f"wrench.{part}.{a}" for part in ("force", "torque") for a in "xyz"]),
        JOINT_TYPE: (T[JOINT_TYPE](header=header(stamp=time(sec=0, nanosec=0),
                                                 frame_id="stage"),
                                   name=["stage_z", "stage_x", "stage_y"][:joints],
                                   position=np.zeros(joints), velocity=np.zeros(0),
                                   effort=np.zeros(0)),
                     [f"position[{i}]" for i in range(joints)]),
    }
    out = {}
    for typ, (msg, paths) in msgs.items():
        raw = bytes(store.serialize_cdr(msg, typ))
        wanted = {"header.stamp.sec", "header.stamp.nanosec", *paths}
        out[typ] = (raw, walk(raw, typ, store.fielddefs, wanted).fields)
    return out


def serialize_many(store: Typestore, msgtype: str, stamp_ns: np.ndarray,
                   values: Mapping[str, np.ndarray], faces: Sequence[str] = (),
                   joints: int = 1) -> np.ndarray:
    """A (n, length) uint8 matrix of CDR messages: the template with stamps and values set."""
    raw, fields = _templates(store, faces, joints)[msgtype]
    n = stamp_ns.size
    matrix = np.tile(np.frombuffer(raw, dtype=np.uint8), (n, 1))
    columns = {"header.stamp.sec": stamp_ns // 1_000_000_000,
               "header.stamp.nanosec": stamp_ns % 1_000_000_000, **values}
    for path, column in columns.items():
        offset, dtype = fields[path]
        typed = np.asarray(column).astype(dtype)
        matrix[:, offset:offset + typed.itemsize] = typed.view(np.uint8).reshape(n, -1)
    return matrix


@dataclass(frozen=True)
class BagTopics:
    """Topic names the synthetic bag uses (the bringup defaults unless changed)."""

    reading: str = "/driver/reading"
    reference: str = "/bench/gauge/wrench"
    position: str = "/bench/stage/joint_states"


def write_press_bag(path: Path | str, signals: PressSignals, storage: str = "sqlite3",
                    topics: BagTopics = BagTopics(), start_ns: int = 1_700_000_000_000_000_000,
                    progress: Callable[[float], None] | None = None,
                    lost: Mapping[str, Sequence[tuple[float, float]]] | None = None) -> Path:
    """Write the signals as a rosbag2 recording; the stage stream is offset by a third sample.

    ``lost`` leaves out the messages of a stream ('reading', 'reference' or 'position')
    in time windows [s of ``signals.t_s``], as a starved recorder or publisher does.
    """
    path = Path(path)
    store = writer_typestore()
    stamp = start_ns + np.round(signals.t_s * 1e9).astype(np.int64)
    dt_ns = int(np.median(np.diff(stamp))) if stamp.size > 1 else 1_000_000
    stage_stamp = stamp + dt_ns // 3
    streams = [
        (topics.reading, READING_TYPE, stamp,
         {"voltage": 2.0 - signals.output_v, "output": signals.output_v,
          "force": signals.output_v / 0.07, "contact": signals.output_v > 0.05}),
        (topics.reference, WRENCH_TYPE, stamp, {"wrench.force.z": signals.force_n}),
        (topics.position, JOINT_TYPE, stage_stamp, {"position[0]": signals.indentation_m}),
    ]
    for role, windows in (lost or {}).items():
        i = ("reading", "reference", "position").index(role)
        topic, msgtype, stamps, values = streams[i]
        t = (stamps - start_ns) * 1e-9
        keep = ~np.any([(t >= a) & (t < b) for a, b in windows], axis=0)
        streams[i] = (topic, msgtype, stamps[keep], {k: np.asarray(v)[keep]
                                                     for k, v in values.items()})
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    with Writer(path, version=9, storage_plugin=plugin) as writer:
        total = sum(s[2].size for s in streams)
        done = 0
        for topic, msgtype, stamps, values in streams:
            conn = writer.add_connection(topic, msgtype, typestore=store)
            matrix = serialize_many(store, msgtype, stamps, values)
            write = writer.write
            for ts, row in zip(stamps.tolist(), matrix, strict=True):
                write(conn, ts, row.tobytes())
            done += stamps.size
            if progress is not None:
                progress(done / total)
    return path


# --- module arrays -------------------------------------------------------------------------

ARRAY_FACES = ("front", "back", "left", "right")
# outputs per newton (faces x [Fx, Fy, Fz]): the face the probe moves toward bulges out
# (right +x, front +y), the opposite one draws in; pressing raises every module
ARRAY_SENSITIVITY_V_PER_N = ((0.01, 0.20, 0.05),
                             (-0.01, -0.20, 0.05),
                             (-0.20, 0.01, 0.05),
                             (0.20, -0.01, 0.05))
SHEAR_DIRECTIONS_RAD = tuple(np.radians([0, 180, 90, 270, 45, 225, 135, 315]))


@dataclass(frozen=True)
class ShearProtocol:
    """Rest, press to depth_m, then per direction (+x, -x, +y, -y, then the diagonals) out
    to shear_m and back, then release and rest, all at speed_mm_s (the contract's shear
    protocol). press=False: the probe is at depth from the first sample to the last (no
    press for the single-module segmentation to find)."""

    depth_m: float = 2e-3
    shear_m: float = 3e-3
    directions: int = 4
    speed_mm_s: float = 2.0
    rest_s: float = 1.0
    rate_hz: float = 200.0
    press: bool = True
    untared_s: float = 0.0  # outputs and driver wrench NaN for this long (before the tare)


@dataclass(frozen=True)
class ArrayTruth:
    """Ground truth of a synthetic array: force from the stage, outputs = S F + c + noise,
    the driver's estimate = F + offset + noise (per axis)."""

    faces: tuple[str, ...] = ARRAY_FACES
    sensitivity_v_per_n: tuple[tuple[float, float, float], ...] = ARRAY_SENSITIVITY_V_PER_N
    output_offset_v: tuple[float, ...] = (0.01, 0.02, 0.03, 0.04)
    output_noise_v: float = 0.0
    force_at_depth_n: float = 6.0
    exponent: float = 1.2
    lateral_n_per_m: float = 400.0  # lateral force per lateral probe displacement
    estimate_offset_n: tuple[float, float, float] = (0.0, 0.0, 0.0)
    estimate_noise_n: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class ShearSignals:
    """Sampled array signals and the truth behind them."""

    t_s: np.ndarray
    stage_m: np.ndarray  # (n, 3): indentation, lateral x, lateral y
    reference_n: np.ndarray  # (n, 3) the gauge
    estimate_n: np.ndarray  # (n, 3) the driver's wrench
    outputs_v: np.ndarray  # (n, k)
    faces: tuple[str, ...]
    estimate_noise_n: np.ndarray  # (n, 3) the noise added to the estimate
    # (n, 3) torque x, y, z [N m], the gauge's and the driver's; None: zero in the bag, as a
    # force-only gauge or driver sends it
    reference_torque_nm: np.ndarray | None = None
    estimate_torque_nm: np.ndarray | None = None


def with_torque(signals: ShearSignals, reference_nm: np.ndarray,
                offset_nm: Sequence[float] = (0.0, 0.0, 0.0),
                unobserved: Sequence[str] = ()) -> ShearSignals:
    """The recording with the gauge's torque ``reference_nm`` (n, 3) [N m] and the driver's
    = reference + ``offset_nm``, NaN along the ``unobserved`` axes ("x", "y", "z": what a
    layout that does not see them publishes) and wherever the driver's force is NaN."""
    reference = np.asarray(reference_nm, dtype=float)
    estimate = reference + np.asarray(offset_nm, dtype=float)
    estimate[:, ["xyz".index(a) for a in unobserved]] = np.nan
    estimate[~np.all(np.isfinite(signals.estimate_n), axis=1)] = np.nan
    return replace(signals, reference_torque_nm=reference, estimate_torque_nm=estimate)


def shear_signals(protocol: ShearProtocol, truth: ArrayTruth, seed: int = 0) -> ShearSignals:
    """Stage path, gauge force, module outputs and driver estimate at protocol.rate_hz."""
    rng = np.random.default_rng(seed)
    v = protocol.speed_mm_s * 1e-3
    knots = [(0.0, 0.0, 0.0, 0.0)]  # (t, d, x, y)

    def go(d: float, x: float, y: float) -> None:
        t, d0, x0, y0 = knots[-1]
        dist = float(np.hypot(np.hypot(d - d0, x - x0), y - y0))
        knots.append((t + dist / v, d, x, y))

    depth = protocol.depth_m
    if protocol.press:
        knots.append((protocol.rest_s, 0.0, 0.0, 0.0))
        go(depth, 0.0, 0.0)
    else:
        knots[0] = (0.0, depth, 0.0, 0.0)
        knots.append((protocol.rest_s, depth, 0.0, 0.0))
    for angle in SHEAR_DIRECTIONS_RAD[:protocol.directions]:
        go(depth, protocol.shear_m * np.cos(angle), protocol.shear_m * np.sin(angle))
        go(depth, 0.0, 0.0)
    if protocol.press:
        go(0.0, 0.0, 0.0)
    t_end = knots[-1][0] + protocol.rest_s
    knots.append((t_end, *knots[-1][1:]))
    k = np.array(knots)
    t = np.arange(round(t_end * protocol.rate_hz)) / protocol.rate_hz
    stage = np.column_stack([np.interp(t, k[:, 0], k[:, j]) for j in (1, 2, 3)])
    fz = truth.force_at_depth_n * np.clip(stage[:, 0] / depth, 0.0, None) ** truth.exponent
    reference = np.column_stack([truth.lateral_n_per_m * stage[:, 1],
                                 truth.lateral_n_per_m * stage[:, 2], fz])
    s = np.asarray(truth.sensitivity_v_per_n, dtype=float)
    outputs = (reference @ s.T + np.asarray(truth.output_offset_v)
               + truth.output_noise_v * rng.standard_normal((t.size, s.shape[0])))
    noise = np.asarray(truth.estimate_noise_n) * rng.standard_normal((t.size, 3))
    estimate = reference + np.asarray(truth.estimate_offset_n) + noise
    untared = t < protocol.untared_s
    outputs[untared] = np.nan
    estimate[untared] = np.nan
    return ShearSignals(t_s=t, stage_m=stage, reference_n=reference, estimate_n=estimate,
                        outputs_v=outputs, faces=tuple(truth.faces), estimate_noise_n=noise)


@dataclass(frozen=True)
class ArrayBagTopics:
    """Topic names of a synthetic array bag (the array bringup's)."""

    reading: str = "/driver/reading"
    estimate: str = "/driver/wrench"
    reference: str = "/bench/gauge/wrench"
    position: str = "/bench/stage/joint_states"


def write_array_bag(path: Path | str, signals: ShearSignals, storage: str = "sqlite3",
                    topics: ArrayBagTopics = ArrayBagTopics(),
                    start_ns: int = 1_700_000_000_000_000_000,
                    omit: Sequence[str] = ()) -> Path:
    """Write an array recording (reading with faces/voltages/outputs, the driver's wrench,
    the gauge's three-axis wrench, the three-axis stage) with the package's own message
    definitions; ``omit`` leaves out streams by role ('reading', 'estimate', 'reference',
    'position'). The stage stream is offset by a third sample, as in write_press_bag."""
    path = Path(path)
    store = writer_typestore()
    faces = signals.faces
    stamp = start_ns + np.round(signals.t_s * 1e9).astype(np.int64)
    dt_ns = int(np.median(np.diff(stamp))) if stamp.size > 1 else 1_000_000
    est = signals.estimate_n
    reading = {"voltage": 2.0 - signals.outputs_v[:, 0], "output": signals.outputs_v[:, 0],
               "force": est[:, 2], "contact": np.nan_to_num(est[:, 2]) > 0.2}
    for i in range(len(faces)):
        reading[f"voltages[{i}]"] = 2.0 - signals.outputs_v[:, i]
        reading[f"outputs[{i}]"] = signals.outputs_v[:, i]

    def wrench(f: np.ndarray, t: np.ndarray | None) -> dict[str, np.ndarray]:
        out = {f"wrench.force.{a}": f[:, j] for j, a in enumerate("xyz")}
        if t is not None:
            out.update({f"wrench.torque.{a}": t[:, j] for j, a in enumerate("xyz")})
        return out

    streams = {
        "reading": (topics.reading, READING_TYPE, stamp, reading),
        "estimate": (topics.estimate, WRENCH_TYPE, stamp,
                     wrench(est, signals.estimate_torque_nm)),
        "reference": (topics.reference, WRENCH_TYPE, stamp,
                      wrench(signals.reference_n, signals.reference_torque_nm)),
        "position": (topics.position, JOINT_TYPE, stamp + dt_ns // 3,
                     {f"position[{j}]": signals.stage_m[:, j] for j in range(3)}),
    }
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    with Writer(path, version=9, storage_plugin=plugin) as writer:
        for role, (topic, msgtype, stamps, values) in streams.items():
            if role in omit:
                continue
            conn = writer.add_connection(topic, msgtype, typestore=store)
            matrix = serialize_many(store, msgtype, stamps, values, faces, joints=3)
            for ts, row in zip(stamps.tolist(), matrix, strict=True):
                writer.write(conn, ts, row.tobytes())
    return path


TRUE_PRONY_G = (0.05, 0.04)  # the mock's (config/physics.yaml), as the default truth
TRUE_PRONY_TAU_S = (0.1, 1.5)


def rate_press_record(speeds_m_s: Sequence[float], hold_s: float = 2.0,
                      g: Sequence[float] = TRUE_PRONY_G,
                      tau_s: Sequence[float] = TRUE_PRONY_TAU_S,
                      rate_hz: float = 1000.0, seed: int = 0, output_noise_v: float = 1e-3,
                      force_noise_n: float = 0.01, play_m: float = 0.0) -> Any:
    """A labelled ``RateRecord`` of one 3 mm press per speed with known rate terms: output
    0.5 V x (play(d) / 3 mm)^0.9 plus noise, force the Prony series on 7 N x (d / 3 mm)^1.3
    plus noise; the truth the rate fit's tests score against."""
    from tactile_sensor.physics.viscoelastic import RateDependentForce
    from tactile_sensor.sim.bench_world import play
    from tactile_sensor.sim.profiles import LoadProfile

    from .rate.record import RateRecord, labels_from_knots

    profile = LoadProfile(depth_m=3e-3, speeds_m_s=tuple(speeds_m_s), cycles=1, hold_s=hold_s,
                          rest_s=1.0)
    t = np.arange(0.0, profile.duration_s, 1.0 / rate_hz)
    d = np.asarray(profile.indentation(t), dtype=float)
    rng = np.random.default_rng(seed)
    output = (0.5 * np.clip(play(d, play_m) / 3e-3, 0.0, None) ** 0.9
              + rng.normal(0.0, output_noise_v, t.size))
    force = RateDependentForce(g, tau_s).force_history(t, 7.0 * (d / 3e-3) ** 1.3)
    force += rng.normal(0.0, force_noise_n, t.size)
    speed, phase = labels_from_knots(t, profile.knots()[0], profile.speeds_m_s)
    return RateRecord(t, output, force, speed, phase)
