"""One storage file of a rosbag2 bag (MCAP or sqlite3) that can be made durable at any time.

rosbags' storage writers keep everything until ``close``: its MCAP writer buffers chunks in
a Python file object and writes schemas and channels only into the first chunk; its sqlite3
writer commits once, at close. A ``kill -9`` after 40 s lost all 13 MB of a bench recording.
These files ``flush()`` on demand instead: the MCAP file closes its chunk (the ``mcap``
library's own writer and chunking) and fsyncs; the sqlite3 file commits (rollback journal,
``synchronous=FULL``, so a killed writer leaves the last commit intact).
"""

from __future__ import annotations

import contextlib
import os
import sqlite3
from pathlib import Path
from typing import Protocol

from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter
from rosbags.interfaces import Connection, MessageDefinitionFormat

#: Channel metadata keys rosbag2's MCAP plugin writes (Jazzy and newer).
QOS_KEY = "offered_qos_profiles"
HASH_KEY = "topic_type_hash"
#: Key of the rosbag2 Metadata record rosbag2 stores inside each MCAP file.
METADATA_NAME = "rosbag2"
METADATA_KEY = "serialized_metadata"
LIBRARY = "tactile_sensor recorder (mcap-python)"


class StorageFile(Protocol):
    """What :class:`~tactile_sensor.recording.rosbag2_writer.Rosbag2Writer` needs of a file."""

    path: Path

    def add_connection(self, connection: Connection, qos_yaml: str) -> None: ...

    def write(self, connection: Connection, timestamp_ns: int, data: bytes) -> None: ...

    def flush(self) -> None: ...

    @property
    def size(self) -> int: ...

    def close(self, metadata_yaml: str) -> None: ...

    def abort(self) -> None: ...


def _schema_encoding(connection: Connection) -> str:
    return "ros2idl" if connection.msgdef.format == MessageDefinitionFormat.IDL else "ros2msg"


class McapFile:
    """A rosbag2 MCAP file written with the ``mcap`` library: chunked, uncompressed (as
    rosbag2's default), CRCs on, so a cut file can be checked chunk by chunk."""

    def __init__(self, path: Path, chunk_bytes: int) -> None:
        self.path = path
        self._stream = path.open("xb")
        self._writer = McapWriter(self._stream, chunk_size=chunk_bytes,
                                  compression=CompressionType.NONE)
        self._writer.start(profile="ros2", library=LIBRARY)
        self._schemas: dict[str, int] = {}
        self._channels: dict[int, int] = {}  # connection id -> channel id in this file

    def add_connection(self, connection: Connection, qos_yaml: str) -> None:
        schema = self._schemas.get(connection.msgtype)
        if schema is None:
            schema = self._writer.register_schema(
                connection.msgtype, _schema_encoding(connection),
                connection.msgdef.data.encode())
            self._schemas[connection.msgtype] = schema
        self._channels[connection.id] = self._writer.register_channel(
            connection.topic, "cdr", schema, {QOS_KEY: qos_yaml, HASH_KEY: connection.digest})

    def write(self, connection: Connection, timestamp_ns: int, data: bytes) -> None:
        self._writer.add_message(self._channels[connection.id], timestamp_ns, data,
                                 timestamp_ns)

    def flush(self) -> None:
        """Close the open chunk and put it on disk (a no-op when it holds no message)."""
        self._writer.flush()
        os.fsync(self._stream.fileno())

    @property
    def size(self) -> int:
        return self._stream.tell()

    def close(self, metadata_yaml: str) -> None:
        self._writer.flush()
        self._writer.add_metadata(METADATA_NAME, {METADATA_KEY: metadata_yaml})
        self._writer.finish()
        self._stream.flush()
        os.fsync(self._stream.fileno())
        self._stream.close()

    def abort(self) -> None:
        """Let go of the file as it is (recoverable up to its last whole chunk)."""
        with contextlib.suppress(OSError):  # a full disk refuses the buffered tail
            self._stream.close()


_SQLITE_SCHEMA = """
CREATE TABLE schema(schema_version INTEGER PRIMARY KEY, ros_distro TEXT NOT NULL);
CREATE TABLE metadata(id INTEGER PRIMARY KEY, metadata_version INTEGER NOT NULL,
                      metadata TEXT NOT NULL);
CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL,
                    serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL,
                    type_description_hash TEXT NOT NULL);
CREATE TABLE message_definitions(id INTEGER PRIMARY KEY, topic_type TEXT NOT NULL,
                                 encoding TEXT NOT NULL,
                                 encoded_message_definition TEXT NOT NULL,
                                 type_description_hash TEXT NOT NULL);
CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL,
                      timestamp INTEGER NOT NULL, data BLOB NOT NULL);
CREATE INDEX timestamp_idx ON messages (timestamp ASC);
INSERT INTO schema(schema_version, ros_distro) VALUES (4, 'rosbags');
"""


class Sqlite3File:
    """A rosbag2 sqlite3 file (schema version 4, as rosbag2 Jazzy and rosbags write it)
    that commits on every flush."""

    def __init__(self, path: Path, metadata_version: int) -> None:
        self.path = path
        if path.exists():
            raise FileExistsError(path)
        self._version = metadata_version
        self._conn = sqlite3.connect(path, check_same_thread=True)
        self._conn.execute("PRAGMA synchronous=FULL")
        self._conn.executescript(_SQLITE_SCHEMA)
        self._types: set[str] = set()

    def add_connection(self, connection: Connection, qos_yaml: str) -> None:
        if connection.msgtype not in self._types:
            self._types.add(connection.msgtype)
            self._conn.execute(
                "INSERT INTO message_definitions (topic_type, encoding, "
                "encoded_message_definition, type_description_hash) VALUES (?, ?, ?, ?)",
                (connection.msgtype, _schema_encoding(connection), connection.msgdef.data,
                 connection.digest))
        self._conn.execute(
            "INSERT INTO topics VALUES (?, ?, ?, ?, ?, ?)",
            (connection.id, connection.topic, connection.msgtype, "cdr", qos_yaml,
             connection.digest))

    def write(self, connection: Connection, timestamp_ns: int, data: bytes) -> None:
        self._conn.execute("INSERT INTO messages (topic_id, timestamp, data) VALUES (?, ?, ?)",
                           (connection.id, timestamp_ns, data))

    def flush(self) -> None:
        self._conn.commit()

    @property
    def size(self) -> int:
        page_count = self._conn.execute("PRAGMA page_count").fetchone()[0]
        page_size = self._conn.execute("PRAGMA page_size").fetchone()[0]
        return int(page_count * page_size)

    def close(self, metadata_yaml: str) -> None:
        self._conn.execute("INSERT INTO metadata (metadata_version, metadata) VALUES (?, ?)",
                           (self._version, metadata_yaml))
        self._conn.commit()
        self._conn.close()

    def abort(self) -> None:
        with contextlib.suppress(sqlite3.Error):
            self._conn.close()  # the uncommitted rest rolls back; the commits stay
