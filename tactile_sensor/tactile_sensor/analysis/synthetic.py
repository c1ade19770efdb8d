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
from dataclasses import dataclass, field
from pathlib import Path

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


def _templates(store: Typestore) -> dict[str, tuple[bytes, dict[str, tuple[int, str]]]]:
    """One serialized message per type and where its stamp and value fields sit in it."""
    T = store.types
    header = T["std_msgs/msg/Header"]
    time = T["builtin_interfaces/msg/Time"]
    vec = T["geometry_msgs/msg/Vector3"]
    msgs = {
        READING_TYPE: (T[READING_TYPE](header=header(stamp=time(sec=0, nanosec=0),
                                                     frame_id="tactile"),
                                       voltage=0.0, output=0.0, force=0.0, contact=False),
                       ["voltage", "output", "force", "contact"]),
        WRENCH_TYPE: (T[WRENCH_TYPE](header=header(stamp=time(sec=0, nanosec=0),
                                                   frame_id="gauge"),
                                     wrench=T["geometry_msgs/msg/Wrench"](
                                         force=vec(x=0.0, y=0.0, z=0.0),
                                         torque=vec(x=0.0, y=0.0, z=0.0))),
                      ["wrench.force.z"]),
        JOINT_TYPE: (T[JOINT_TYPE](header=header(stamp=time(sec=0, nanosec=0),
                                                 frame_id="stage"),
                                   name=["z"], position=np.zeros(1), velocity=np.zeros(0),
                                   effort=np.zeros(0)),
                     ["position[0]"]),
    }
    out = {}
    for typ, (msg, paths) in msgs.items():
        raw = bytes(store.serialize_cdr(msg, typ))
        wanted = {"header.stamp.sec", "header.stamp.nanosec", *paths}
        out[typ] = (raw, walk(raw, typ, store.fielddefs, wanted).fields)
    return out


def serialize_many(store: Typestore, msgtype: str, stamp_ns: np.ndarray,
                   values: Mapping[str, np.ndarray]) -> np.ndarray:
    """A (n, length) uint8 matrix of CDR messages: the template with stamps and values set."""
    raw, fields = _templates(store)[msgtype]
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
