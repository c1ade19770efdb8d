"""A rosbag2 writer that never blocks its caller and survives being killed.

PyPI has no rosbag2, so bags are written by :mod:`.rosbag2_writer` (the ``mcap`` library's
chunked writer, or sqlite3), with type definitions and hashes from ``rosbags``. ROS
callbacks hand serialized CDR to :meth:`BagRecorder.write`, which only enqueues it; a
writer thread does the disk I/O, so an executor is never stalled by a slow disk, and
makes the bag durable every 0.5 s even when no message arrives. Every connection carries
its full message definition and RIHS01 type hash, so ``ros2 bag info``, Foxglove and
PlotJuggler read the bags without our interface packages installed.
"""

from __future__ import annotations

import os
import queue
import sqlite3
import threading
import time
from collections.abc import Mapping
from pathlib import Path
from types import TracebackType
from typing import NamedTuple

from rosbags.interfaces import Connection, Qos
from rosbags.rosbag2.metadata import ReaderError, parse_qos
from rosbags.typesys import Stores, TypesysError, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

from .errors import RecordingError
from .rosbag2_writer import SUFFIXES, Rosbag2Writer, WriterOptions

STORAGES: tuple[str, ...] = tuple(SUFFIXES)
"""Storage names accepted by :class:`BagRecorder`, as ``ros2 bag record -s`` spells them."""

OWN_INTERFACES = "tactile_sensor_interfaces"
# Source-tree fallback when the workspace is not sourced: <repo>/tactile_sensor_interfaces.
_SOURCE_INTERFACES = Path(__file__).resolve().parents[3] / OWN_INTERFACES
_BATCH = 1024  # messages written per lock acquisition by the writer thread


_TICK = object()  # the writer thread's own wake-up: time to make the bag durable


class _Message(NamedTuple):
    topic: str
    timestamp_ns: int
    cdr: bytes


class _AddTopic(NamedTuple):
    topic: str
    msgtype: str
    msgdef: str
    digest: str
    profiles: list[Qos]


def _newest_ros2_store() -> Stores:
    """Kilted (the distro of our wheels) if this rosbags knows it, else its newest ROS 2 store."""
    names = [store.name for store in Stores]
    if "ROS2_KILTED" in names:
        return Stores.ROS2_KILTED
    return Stores[sorted(n for n in names if n.startswith("ROS2_"))[-1]]


def _interface_dirs(package: str) -> list[Path]:
    """``share/<package>/msg`` folders on AMENT_PREFIX_PATH, then the source tree for ours."""
    prefixes = [p for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    dirs = [Path(p) / "share" / package / "msg" for p in prefixes]
    if package == OWN_INTERFACES:
        dirs.append(_SOURCE_INTERFACES / "msg")
    return [d for d in dirs if d.is_dir()]


def register_package(typestore: Typestore, package: str) -> int:
    """Register every ``.msg`` of ``package`` found on disk; returns how many were found."""
    for folder in _interface_dirs(package):
        types = {}
        for msg_file in sorted(folder.glob("*.msg")):
            types.update(get_types_from_msg(
                msg_file.read_text(encoding="utf-8"), f"{package}/msg/{msg_file.stem}"))
        if types:
            typestore.register(types)
            return len(types)
    return 0


def default_typestore() -> Typestore:
    """The standard ROS 2 types plus ours (from the installed or source .msg files)."""
    typestore = get_typestore(_newest_ros2_store())
    register_package(typestore, OWN_INTERFACES)
    return typestore


def normalize_msgtype(msgtype: str) -> str:
    """``pkg/Type`` -> ``pkg/msg/Type`` (the spelling the ROS graph and bags use)."""
    parts = msgtype.strip().split("/")
    if len(parts) == 2 and all(parts):
        return f"{parts[0]}/msg/{parts[1]}"
    return msgtype.strip()


class BagRecorder:
    """A rosbag2 folder being recorded; use as a context manager, or ``open()``/``close()``.

    ``write`` may be called from any thread and returns at once; ``close`` writes what is
    still queued and then the metadata, so a bag closed normally holds every message given,
    and a killed process leaves all but the last ``flush_period_s`` or so on disk.
    The storage writer lives entirely in the writer thread (sqlite3 connections must
    stay in the thread that made them), fed through one FIFO queue, so topics are always
    added before their first message is written.
    """

    def __init__(
        self,
        path: Path | str,
        storage: str = "mcap",
        *,
        typestore: Typestore | None = None,
        custom_data: Mapping[str, str] | None = None,
        options: WriterOptions | None = None,
    ) -> None:
        self.path = Path(path)
        if storage not in STORAGES:
            raise RecordingError(
                f"Storage '{storage}' is unknown; use one of {', '.join(STORAGES)}.")
        self.storage = storage
        if self.path.exists():
            raise RecordingError(
                f"Bag folder {self.path} exists already; choose a new path or remove it.")
        self._typestore = typestore if typestore is not None else default_typestore()
        self._custom_data = dict(custom_data or {})
        self._options = options or WriterOptions()
        self._durable = 0  # messages on disk in whole chunks, set by the writer thread
        self._started_s = 0.0
        self._failed_after_s: float | None = None
        self._msgtypes: dict[str, str] = {}
        self._counts: dict[str, int] = {}  # keys added by the caller, values by the thread
        self._queue: queue.SimpleQueue[_Message | _AddTopic | None] = queue.SimpleQueue()
        self._accept = threading.Lock()  # orders write()/add_topic() against close()
        self._thread: threading.Thread | None = None
        self._failure: BaseException | None = None
        self._files: list[str] = []
        self._open = False
        self._closed = False

    # -- lifecycle ------------------------------------------------------------------------

    def open(self) -> BagRecorder:
        """Create the bag folder and start the writer thread."""
        if self._thread is not None or self._closed:
            raise RecordingError(f"Bag {self.path} was opened already; create a new recorder.")
        writer = Rosbag2Writer(self.path, self.storage, self._options, self._custom_data)
        opened = threading.Event()
        self._started_s = time.monotonic()
        self._thread = threading.Thread(
            target=self._run, args=(writer, opened), name=f"bag-writer:{self.path.name}",
            daemon=True)
        self._thread.start()
        opened.wait()
        failure = self._failure
        if isinstance(failure, FileExistsError):
            self._closed = True
            raise RecordingError(
                f"Bag folder {self.path} exists already; choose a new path or remove it.")
        if isinstance(failure, OSError):
            self._closed = True
            raise RecordingError(
                f"Cannot create bag folder {self.path} ({failure.strerror or failure}); "
                "choose a folder you can write to.")
        self._open = True
        return self

    def close(self) -> None:
        """Write everything queued, then the index and metadata.yaml; safe to call twice."""
        with self._accept:
            if self._closed:
                return
            self._closed = True
            self._open = False
            if self._thread is not None:
                self._queue.put(None)
        if self._thread is not None:
            self._thread.join()
        self._raise_failure()

    def __enter__(self) -> BagRecorder:
        return self.open()

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        # Finish the bag even when the caller failed: what was recorded stays readable.
        self.close()

    # -- topics and messages ----------------------------------------------------------------

    def add_topic(self, name: str, msgtype: str, qos_profile_yaml: str | None = None) -> None:
        """Declare a topic, its type (``pkg/msg/Type``) and the QoS its publishers offered.

        ``qos_profile_yaml`` is rosbag2's ``offered_qos_profiles`` text: a YAML (or JSON)
        list of mappings with history, depth, reliability, durability, deadline, lifespan,
        liveliness, liveliness_lease_duration and avoid_ros_namespace_conventions.
        """
        msgtype = normalize_msgtype(msgtype)
        known = self._msgtypes.get(name)
        if known is not None:
            if known == msgtype:
                return
            raise RecordingError(
                f"Topic {name} is recorded as {known} already and cannot also be {msgtype}; "
                "record the second type under another topic name.")
        msgdef, digest = self._definition(msgtype)
        profiles = self._parse_qos(name, qos_profile_yaml)
        with self._accept:
            self._require_open()
            self._counts[name] = 0
            self._msgtypes[name] = msgtype
            self._queue.put(_AddTopic(name, msgtype, msgdef, digest, profiles))

    def write(self, topic: str, timestamp_ns: int, cdr: bytes) -> None:
        """Queue one serialized message; returns at once, from any thread."""
        if topic not in self._msgtypes:
            raise RecordingError(
                f"Topic {topic} was not added to bag {self.path}; call add_topic() first.")
        if not 0 <= timestamp_ns < 2**63:
            raise RecordingError(
                f"Timestamp {timestamp_ns} for {topic} is outside 0..2**63-1 ns; pass "
                "nanoseconds since the epoch.")
        with self._accept:
            self._require_open()
            self._queue.put(_Message(topic, int(timestamp_ns), bytes(cdr)))

    # -- state --------------------------------------------------------------------------------

    @property
    def topics(self) -> dict[str, str]:
        """Recorded topic -> message type."""
        return dict(self._msgtypes)

    @property
    def counts(self) -> dict[str, int]:
        """Messages written to storage so far, per topic."""
        return dict(self._counts)

    @property
    def kept(self) -> int:
        """Messages on disk in whole chunks: what a crash at this moment would keep."""
        return self._durable

    @property
    def failed_after_s(self) -> float | None:
        """Seconds from open() to a storage failure, None while storage works."""
        return self._failed_after_s

    @property
    def files(self) -> list[str]:
        """The bag's storage files so far (``<bag>_0.mcap``, ...)."""
        return list(self._files)

    @property
    def pending(self) -> int:
        """Messages queued but not yet written."""
        return self._queue.qsize()

    @property
    def is_open(self) -> bool:
        return self._open

    # -- internals ------------------------------------------------------------------------------

    def _require_open(self) -> None:
        if not self._open:
            raise RecordingError(
                f"Bag {self.path} is not open for writing; open it (or use 'with') first.")
        self._raise_failure()

    def _definition(self, msgtype: str) -> tuple[str, str]:
        """Full message definition text and RIHS01 hash, loading unknown packages from disk."""
        for attempt in range(2):
            try:
                msgdef, _ = self._typestore.generate_msgdef(msgtype, ros_version=2)
                return msgdef, self._typestore.hash_rihs01(msgtype)
            except (TypesysError, KeyError):
                package = msgtype.split("/", 1)[0]
                if attempt or not package or not register_package(self._typestore, package):
                    break
        raise RecordingError(
            f"Message type '{msgtype}' is unknown to the recorder; check its spelling "
            "(pkg/msg/Type) or source the workspace that defines it.")

    @staticmethod
    def _parse_qos(topic: str, text: str | None) -> list[Qos]:
        if not text:
            return []
        try:
            return parse_qos(text)
        except (ReaderError, KeyError, TypeError, ValueError, AttributeError):
            raise RecordingError(
                f"QoS profiles given for {topic} are not rosbag2 offered_qos_profiles YAML; "
                "pass a YAML list of profiles or None."
            ) from None

    def _raise_failure(self) -> None:
        if self._failure is not None:
            raise RecordingError(
                f"Writing bag {self.path} failed ({self._failure}); {self._durable} messages "
                "up to the failure are kept (read them with 'tactile-sensor bag recover'); "
                "free disk space or choose another folder and record again.")

    def _fail(self, writer: Rosbag2Writer, exc: BaseException) -> None:
        self._failure = exc
        self._failed_after_s = time.monotonic() - self._started_s
        writer.abort()

    def _run(self, writer: Rosbag2Writer, opened: threading.Event) -> None:
        """Writer thread: open, then batch queued items into storage until the close marker,
        making the bag durable every ``flush_period_s`` even while no message comes."""
        try:
            writer.open()
        except OSError as exc:
            self._failure = exc
            return
        finally:
            opened.set()
        self._files = writer.files
        connections: dict[str, Connection] = {}
        counts = self._counts
        period = self._options.flush_period_s
        # the writer's flush clock starts now: its first tick only starts it, so at the first
        # deadline a message written at the start would still wait a second period (1.0 s)
        writer.tick(time.monotonic())
        deadline = time.monotonic() + period
        stop = False
        while not stop:
            try:
                item = self._queue.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                item = _TICK
            batch: list[_Message | _AddTopic] = []
            while item is not None and item is not _TICK:
                batch.append(item)
                if len(batch) >= _BATCH:
                    break
                try:
                    item = self._queue.get_nowait()
                except queue.Empty:
                    break
            stop = item is None
            if self._failure is not None:
                continue  # keep consuming so close() returns; the failure is reported there
            try:
                for entry in batch:
                    if type(entry) is _Message:
                        writer.write(connections[entry.topic], entry.timestamp_ns, entry.cdr)
                        counts[entry.topic] += 1
                    else:
                        add = entry
                        connections[add.topic] = writer.add_connection(
                            add.topic, add.msgtype, add.msgdef, add.digest, add.profiles)
                now = time.monotonic()
                if now >= deadline:
                    writer.tick(now)
                    deadline = now + period
                self._durable = writer.durable_count
                self._files = writer.files
            except (OSError, sqlite3.Error) as exc:
                self._fail(writer, exc)
        if self._failure is not None:
            return
        try:
            writer.close()
            self._durable = writer.durable_count
        except (OSError, sqlite3.Error) as exc:
            self._fail(writer, exc)
