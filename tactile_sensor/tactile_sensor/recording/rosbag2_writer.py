"""A rosbag2 folder written so that a killed recorder loses at most the last chunk.

Replaces ``rosbags.rosbag2.Writer`` (which cannot flush before ``close``) with the same
output on a clean close: metadata.yaml version 8 with type hashes and offered QoS, and the
rosbag2 metadata record inside each MCAP file. The differences:

- a chunk (MCAP) or transaction (sqlite3) is closed and made durable every
  ``flush_period_s`` (0.5 s: with the writer thread's own latency, everything older than
  about a second is on disk) or every ``chunk_bytes`` (1 MiB, as rosbag2 and rosbags);
- the bag is split like rosbag2's ``--max-bag-duration`` / ``--max-bag-size`` into
  ``<bag>_0.mcap``, ``<bag>_1.mcap``, ... (rosbag2's names, also when nothing splits).

Single-threaded: :class:`~tactile_sensor.recording.bag_writer.BagRecorder` owns it in its
writer thread and calls :meth:`tick` with the time.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from io import StringIO
from pathlib import Path
from typing import Any

from rosbags.interfaces import (
    Connection,
    ConnectionExtRosbag2,
    MessageDefinition,
    MessageDefinitionFormat,
    Qos,
)
from rosbags.rosbag2.metadata import dump_qos_v8
from ruamel.yaml import YAML

from .storage_files import McapFile, Sqlite3File, StorageFile

# Metadata version 8 is what Jazzy writes; Jazzy and every newer rosbag2 read it.
BAG_VERSION = 8
FLUSH_PERIOD_S = 0.5
CHUNK_BYTES = 1 << 20
SUFFIXES = {"mcap": ".mcap", "sqlite3": ".db3"}


@dataclass(frozen=True)
class WriterOptions:
    """How often the bag is made durable and when it is split (0 = never)."""

    flush_period_s: float = FLUSH_PERIOD_S
    chunk_bytes: int = CHUNK_BYTES
    max_bag_duration_s: float = 0.0
    max_bag_size_bytes: int = 0


@dataclass
class _FileStats:
    name: str
    start_ns: int = 2**63 - 1
    end_ns: int = 0
    count: int = 0

    def add(self, timestamp_ns: int) -> None:
        self.start_ns = min(self.start_ns, timestamp_ns)
        self.end_ns = max(self.end_ns, timestamp_ns)
        self.count += 1


@dataclass
class _Topic:
    connection: Connection
    qos_yaml: str
    count: int = 0


def _yaml_text(data: Any) -> str:
    yaml = YAML(typ="safe")
    yaml.default_flow_style = False
    out = StringIO()
    yaml.dump(data, out)
    return out.getvalue()


def qos_yaml(profiles: Sequence[Qos]) -> str:
    """Offered QoS profiles as rosbag2 version 8 stores them (a YAML string)."""
    dumped = dump_qos_v8(list(profiles))
    return dumped if isinstance(dumped, str) else _yaml_text(dumped).strip()


class Rosbag2Writer:
    """A new rosbag2 folder: ``open``, ``add_connection``, ``write``, ``tick``, ``close``."""

    def __init__(self, path: Path | str, storage: str = "mcap",
                 options: WriterOptions | None = None,
                 custom_data: Mapping[str, str] | None = None) -> None:
        self.path = Path(path)
        if storage not in SUFFIXES:
            raise ValueError(storage)
        self.storage = storage
        self.options = options or WriterOptions()
        self.custom_data = dict(custom_data or {})
        self._topics: list[_Topic] = []
        self._files: list[_FileStats] = []
        self._file: StorageFile | None = None
        self._last_flush_s: float | None = None
        self._durable = 0  # messages in chunks that reached the disk
        self._written = 0

    # -- lifecycle ------------------------------------------------------------------------
    def open(self) -> None:
        """Create the folder (FileExistsError if it exists) and its first file."""
        self.path.mkdir(mode=0o755, parents=True)
        self._open_file()

    def close(self) -> None:
        """Flush, finish the open file with its index, write metadata.yaml atomically."""
        assert self._file is not None, "close() before open()"
        self._file.flush()
        self._durable = self._written
        self._file.close(_yaml_text(self._info()).strip())
        self._file = None
        tmp = self.path / "metadata.yaml.tmp"
        with tmp.open("w", encoding="utf-8") as out:
            out.write(_yaml_text({"rosbag2_bagfile_information": self._info()}))
            out.flush()
            os.fsync(out.fileno())
        tmp.replace(self.path / "metadata.yaml")

    def abort(self) -> None:
        """Stop without index or metadata (after a storage failure); the flushed chunks
        stay readable by ``tactile-sensor bag recover``."""
        file, self._file = self._file, None
        if file is not None:
            file.abort()

    # -- content ----------------------------------------------------------------------------
    def add_connection(self, topic: str, msgtype: str, msgdef: str, digest: str,
                       profiles: Sequence[Qos] = ()) -> Connection:
        assert self._file is not None, "add_connection() before open()"
        fmt = (MessageDefinitionFormat.IDL if msgdef.startswith("=" * 80 + "\nIDL: ")
               else MessageDefinitionFormat.MSG)
        connection = Connection(
            id=len(self._topics) + 1, topic=topic, msgtype=msgtype,
            msgdef=MessageDefinition(fmt, msgdef), digest=digest, msgcount=0,
            ext=ConnectionExtRosbag2(serialization_format="cdr",
                                     offered_qos_profiles=list(profiles)),
            owner=self)
        entry = _Topic(connection, qos_yaml(profiles))
        self._topics.append(entry)
        self._file.add_connection(connection, entry.qos_yaml)
        return connection

    def write(self, connection: Connection, timestamp_ns: int, data: bytes) -> None:
        assert self._file is not None, "write() before open()"
        current = self._files[-1]
        limit_ns = int(self.options.max_bag_duration_s * 1e9)
        if limit_ns and current.count and timestamp_ns - current.start_ns >= limit_ns:
            self._split()
            current = self._files[-1]
        self._file.write(connection, timestamp_ns, data)
        current.add(timestamp_ns)
        self._topics[connection.id - 1].count += 1
        self._written += 1

    def tick(self, now_s: float) -> None:
        """Make the bag durable when ``flush_period_s`` passed since the last time."""
        if self._last_flush_s is None:
            self._last_flush_s = now_s
        if now_s - self._last_flush_s >= self.options.flush_period_s:
            self.flush()
            self._last_flush_s = now_s

    def flush(self) -> None:
        """Close the chunk (commit) and fsync; split when the file reached its size."""
        assert self._file is not None
        self._file.flush()
        self._durable = self._written
        limit = self.options.max_bag_size_bytes
        if limit and self._files[-1].count and self._file.size >= limit:
            self._split()

    # -- state ------------------------------------------------------------------------------
    @property
    def durable_count(self) -> int:
        """Messages that reached the disk in whole chunks: what a crash now would keep."""
        return self._durable

    @property
    def files(self) -> list[str]:
        return [f.name for f in self._files]

    # -- internals ----------------------------------------------------------------------------
    def _open_file(self) -> None:
        name = f"{self.path.name}_{len(self._files)}{SUFFIXES[self.storage]}"
        file: StorageFile
        if self.storage == "mcap":
            file = McapFile(self.path / name, self.options.chunk_bytes)
        else:
            file = Sqlite3File(self.path / name, BAG_VERSION)
        self._files.append(_FileStats(name))
        self._file = file
        for topic in self._topics:
            file.add_connection(topic.connection, topic.qos_yaml)

    def _split(self) -> None:
        assert self._file is not None
        self._file.flush()
        self._durable = self._written
        self._file.close(_yaml_text(self._info()).strip())
        self._open_file()

    def _info(self) -> dict[str, Any]:
        """rosbag2_bagfile_information as rosbags' Writer writes it (version 8)."""
        files = [f for f in self._files if f.count] or self._files[:1]
        start = min((f.start_ns for f in files if f.count), default=2**63 - 1)
        end = max((f.end_ns for f in files if f.count), default=0)
        duration = max(0, end - start)
        return {
            "version": BAG_VERSION,
            "storage_identifier": self.storage,
            "relative_file_paths": [f.name for f in self._files],
            "duration": {"nanoseconds": duration},
            "starting_time": {"nanoseconds_since_epoch": start},
            "message_count": sum(f.count for f in self._files),
            "topics_with_message_count": [
                {"topic_metadata": {
                    "name": t.connection.topic,
                    "type": t.connection.msgtype,
                    "serialization_format": "cdr",
                    "offered_qos_profiles": t.qos_yaml,
                    "type_description_hash": t.connection.digest},
                 "message_count": t.count}
                for t in self._topics],
            "compression_format": "",
            "compression_mode": "",
            "files": [
                {"path": f.name,
                 "starting_time": {"nanoseconds_since_epoch": f.start_ns if f.count else 0},
                 "duration": {"nanoseconds": max(0, f.end_ns - f.start_ns)},
                 "message_count": f.count}
                for f in self._files],
            "custom_data": self.custom_data or None,
            "ros_distro": "rosbags",
        }
