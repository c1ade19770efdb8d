"""Read the few fields the analysis needs from a rosbag2 recording (sqlite3 or MCAP).

rosbags supplies the raw CDR bytes; ``cdr_columns`` turns them into numpy columns.
Every low-level failure (missing path, truncated file, corrupt database) becomes a
``BagError`` here, at the boundary.
"""

from __future__ import annotations

import struct
import tempfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import apsw
import numpy as np
from rosbags.rosbag2 import Reader
from rosbags.rosbag2.errors import ReaderError

from .cdr_columns import CdrLayoutError, decode_columns, missing_fields, read_strings
from .errors import BagError, TopicError
from .message_types import field_definitions

_STAMP_PATHS = ("header.stamp.sec", "header.stamp.nanosec")
# Errors rosbags and its storage back-ends let through on damaged files.
_READ_ERRORS = (ReaderError, apsw.Error, OSError, struct.error, EOFError, ValueError,
                KeyError, IndexError)

Progress = Callable[[float], None]
Notify = Callable[[str], None]  # gets the one line saying what a recovery found


@dataclass(frozen=True)
class TopicSpec:
    """One topic the analysis reads: its role, name, and which fields under which names."""

    role: str
    topic: str
    fields: dict[str, str]  # our name -> field path, e.g. "force_n": "wrench.force.z"
    option: str  # the CLI option that sets the topic, for error messages
    expected_type: str  # what the user should point the option at
    # decoded only when the type declares them (module arrays, lateral force): our name ->
    # field path; absent ones are simply not in Series.values
    optional: dict[str, str] = field(default_factory=dict)
    # float sequences read whole (our name -> sequence path, e.g. "outputs"): an (n, k)
    # matrix in Series.arrays, k the longest sequence, NaN-padded; only if declared
    sequences: dict[str, str] = field(default_factory=dict)
    # string sequences (our name -> path, e.g. "faces"): read from one message holding the
    # longest one, into Series.labels
    labels: dict[str, str] = field(default_factory=dict)
    # False: a topic the analysis can do without; its absence is recorded in
    # Recording.absent (the sentence to raise if it turns out to be needed)
    required: bool = True


@dataclass(frozen=True)
class Series:
    """Samples of one topic, ordered by time."""

    topic: str
    msgtype: str
    stamp_ns: np.ndarray  # int64; header stamps unless they were all zero
    values: dict[str, np.ndarray]
    stamp_source: str  # "header" or "bag"
    arrays: dict[str, np.ndarray] = field(default_factory=dict)  # name -> (n, k)
    labels: dict[str, list[str]] = field(default_factory=dict)


@dataclass(frozen=True)
class Recording:
    """What one bag holds for the analysis."""

    path: Path
    storage: str
    series: dict[str, Series]
    notes: list[str] = field(default_factory=list)
    absent: dict[str, str] = field(default_factory=dict)  # optional role -> why it is missing


def storage_of(path: Path) -> str:
    """'sqlite3' or 'mcap' (by file suffix), 'unknown' when neither is recognisable."""
    files = [path] if path.is_file() else list(path.iterdir()) if path.is_dir() else []
    suffixes = {p.suffix for p in files}
    if ".mcap" in suffixes:
        return "mcap"
    if ".db3" in suffixes:
        return "sqlite3"
    return "unknown"


def _bag_error(path: Path, err: BaseException) -> BagError:
    detail = str(err).strip().rstrip(".") or type(err).__name__
    return BagError(f"cannot read the bag {path} ({detail}); it may be truncated or corrupt "
                    "- re-record it or pass the rosbag2 directory or its .db3/.mcap file.")


def open_reader(path: Path) -> Reader:
    """An opened rosbags Reader, or a BagError that says why not."""
    if not path.exists():
        raise BagError(f"the bag {path} does not exist; pass a rosbag2 directory or a "
                       ".db3/.mcap file.")
    try:
        reader = Reader(path)
        reader.open()
    except _READ_ERRORS as err:
        raise _bag_error(path, err) from None
    return reader


def read_recording(path: Path | str, specs: Sequence[TopicSpec],
                   progress: Progress | None = None,
                   notify: Notify | None = None) -> Recording:
    """Read the specified topics; progress(fraction of selected messages read).

    A bag a killed recorder left (no metadata.yaml, MCAP files cut off, an interrupted
    sqlite3 transaction) is recovered into a temporary bag first, and ``notify`` gets the
    one line saying how many messages came from which files."""
    path = Path(path)
    try:
        reader = open_reader(path)
        try:
            return _read(reader, path, specs, progress)
        finally:
            reader.close()
    except BagError:
        if not path.exists():
            raise
    return _read_recovered(path, specs, progress, notify)


def _read_recovered(path: Path, specs: Sequence[TopicSpec], progress: Progress | None,
                    notify: Notify | None) -> Recording:
    from tactile_sensor.recording import RecordingError
    from tactile_sensor.recording.recovery import recover

    with tempfile.TemporaryDirectory(prefix="tactile-analyze-") as tmp:
        try:
            recovery = recover(path, Path(tmp) / "recovered")
        except RecordingError as err:
            raise BagError(f"cannot read the bag {path}: {err}") from None
        if recovery.message_count == 0:
            raise BagError(f"cannot read the bag {path}: it holds no whole chunk of "
                           f"messages ({recovery.summary()}); record again.") from None
        line = recovery.summary()
        if notify is not None:
            notify(line)
        reader = open_reader(recovery.out)
        try:
            recording = _read(reader, path, specs, progress)
        finally:
            reader.close()
    recording.notes.insert(0, f"{line} (the bag was not closed by its recorder)")
    return recording


def _read(reader: Reader, path: Path, specs: Sequence[TopicSpec],
          progress: Progress | None) -> Recording:
    topics = reader.topics
    defs = field_definitions(reader.connections)
    chosen = {}
    absent: dict[str, str] = {}
    for spec in specs:
        problem = _topic_problem(spec, path, topics, defs)
        if problem is not None:
            if spec.required:
                raise TopicError(problem)
            absent[spec.role] = problem
            continue
        info = topics[spec.topic]
        chosen[spec.role] = (spec, info.msgtype or "", info.connections)

    conn_role = {c.id: role for role, (_, _, conns) in chosen.items() for c in conns}
    total = sum(c.msgcount for _, _, conns in chosen.values() for c in conns)
    raws: dict[str, list[bytes]] = {role: [] for role in chosen}
    bag_ns: dict[str, list[int]] = {role: [] for role in chosen}
    appenders = {cid: (raws[role].append, bag_ns[role].append)
                 for cid, role in conn_role.items()}
    step = max(1, total // 100)
    mark, count = step, 0
    connections = [c for _, _, conns in chosen.values() for c in conns]
    try:
        for conn, stamp, data in reader.messages(connections=connections):
            add_raw, add_ns = appenders[conn.id]
            add_raw(data)
            add_ns(stamp)
            count += 1
            if count >= mark and progress is not None:
                progress(min(count / total, 1.0))
                mark += step
    except _READ_ERRORS as err:
        raise _bag_error(path, err) from None
    if progress is not None:
        progress(1.0)

    notes: list[str] = []
    series = {}
    for role, (spec, msgtype, _) in chosen.items():
        if not raws[role]:
            problem = (f"topic {spec.topic} has no messages in the bag {path}; "
                       f"record it or pass {spec.option} naming another topic.")
            if spec.required:
                raise TopicError(problem)
            absent[role] = problem
            continue
        series[role] = _decode(path, spec, msgtype, defs, raws[role], bag_ns[role], notes)
    return Recording(path=path, storage=storage_of(path), series=series, notes=notes,
                     absent=absent)


def _topic_problem(spec: TopicSpec, path: Path, topics: dict, defs: dict) -> str | None:
    """The sentence saying why a topic cannot be read, or None when it can."""
    if spec.topic not in topics:
        have = ", ".join(sorted(topics)) or "no topics"
        return (f"topic {spec.topic} is not in the bag {path} (it has: {have}); "
                f"pass {spec.option} naming the {spec.expected_type} topic.")
    info = topics[spec.topic]
    msgtype = info.msgtype or ""
    missing = missing_fields(msgtype, defs, list(spec.fields.values()))
    if missing:
        return (f"topic {spec.topic} carries {msgtype or 'mixed types'}, which "
                f"has no field {missing[0]}; pass {spec.option} naming the "
                f"{spec.expected_type} topic.")
    if info.msgcount == 0:
        return (f"topic {spec.topic} has no messages in the bag {path}; "
                f"record it or pass {spec.option} naming another topic.")
    return None


def _decode(path: Path, spec: TopicSpec, msgtype: str, defs: dict, raws: list[bytes],
            bag_ns: list[int], notes: list[str]) -> Series:
    has_header = not missing_fields(msgtype, defs, list(_STAMP_PATHS))
    fields = dict(spec.fields)
    fields.update({k: p for k, p in spec.optional.items()
                   if not missing_fields(msgtype, defs, [p])})
    sequences = {k: p for k, p in spec.sequences.items()
                 if not missing_fields(msgtype, defs, [p])}
    labels = {k: p for k, p in spec.labels.items() if not missing_fields(msgtype, defs, [p])}
    lengths = [f"len({p})" for p in (*sequences.values(), *labels.values())]
    paths = (list(fields.values()) + lengths
             + (list(_STAMP_PATHS) if has_header else []))
    try:
        cols = decode_columns(raws, msgtype, defs, paths)
        arrays = {}
        for name, seq in sequences.items():
            k = _longest(cols[f"len({seq})"])
            items = [f"{seq}[{i}]" for i in range(k)]
            got = decode_columns(raws, msgtype, defs, items) if k else {}
            arrays[name] = (np.column_stack([got[p] for p in items]) if k
                            else np.empty((len(raws), 0)))
        texts = {}
        for name, seq in labels.items():
            column = cols[f"len({seq})"]
            k = _longest(column)
            first = int(np.flatnonzero(column == k)[0]) if k else 0
            found = read_strings(raws[first], msgtype, defs, [f"{seq}[{i}]" for i in range(k)])
            texts[name] = [t or "" for t in found]
    except CdrLayoutError as err:
        raise BagError(f"messages on {spec.topic} in the bag {path} do not match their type "
                       f"{msgtype} ({err}); the bag is corrupt or its definitions are "
                       "wrong - re-record it.") from None
    received = np.asarray(bag_ns, dtype=np.int64)
    stamp_source = "header"
    if has_header:
        stamps = (cols[_STAMP_PATHS[0]].astype(np.int64) * 1_000_000_000
                  + cols[_STAMP_PATHS[1]].astype(np.int64))
        if not np.any(stamps):
            stamps, stamp_source = received, "bag"
            notes.append(f"{spec.topic}: header stamps are all zero; used the bag's receive "
                         "times instead.")
    else:
        stamps, stamp_source = received, "bag"
        notes.append(f"{spec.topic}: {msgtype} has no header; used the bag's receive times.")
    order = np.argsort(stamps, kind="stable")
    values = {name: cols[p][order] for name, p in fields.items()}
    return Series(topic=spec.topic, msgtype=msgtype, stamp_ns=stamps[order], values=values,
                  stamp_source=stamp_source,
                  arrays={name: a[order] for name, a in arrays.items()}, labels=texts)


def _longest(lengths: np.ndarray) -> int:
    finite = lengths[np.isfinite(lengths)]
    return int(finite.max()) if finite.size else 0
