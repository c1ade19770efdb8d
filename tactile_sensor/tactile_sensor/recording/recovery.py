"""Recover what a killed or starved recorder left: ``ros2 bag reindex`` + ``mcap recover``.

A cut MCAP file is read front to back with the ``mcap`` library's ``StreamReader``, which
needs neither summary nor footer; it stops with an error at the first incomplete record,
so every chunk before the cut is kept whole (each checked against its CRC) and the cut one
is dropped. A sqlite3 file is opened on a copy with its journal, so sqlite rolls back the
transaction the kill interrupted and the commits before it stay. What is found is written
as a new, whole rosbag2 bag (index, metadata.yaml) with :class:`Rosbag2Writer`.
"""

from __future__ import annotations

import functools
import re
import shutil
import sqlite3
import struct
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

from mcap.exceptions import EndOfFile, McapError
from mcap.records import Channel, Chunk, Footer, Message, Schema
from mcap.stream_reader import StreamReader, breakup_chunk

from .errors import RecordingError
from .rosbag2_writer import Rosbag2Writer, WriterOptions
from .storage_files import HASH_KEY

MCAP_MAGIC = b"\x89MCAP0\r\n"
SQLITE_MAGIC = b"SQLite format 3\x00"
# What the mcap stream reader raises at a cut or on garbage.
_CUT = (McapError, struct.error, ValueError, UnicodeDecodeError, EOFError, MemoryError)


@dataclass(frozen=True)
class Topic:
    name: str
    msgtype: str
    msgdef: str
    digest: str
    qos_yaml: str


@dataclass
class FileContent:
    """What one storage file still holds."""

    name: str
    topics: list[Topic] = field(default_factory=list)
    # (topic index, timestamp ns, cdr)
    messages: list[tuple[int, int, bytes]] = field(default_factory=list)
    complete: bool = False
    problem: str = ""


@dataclass(frozen=True)
class Recovery:
    """A recovered bag: where it was written and what went into it."""

    source: Path
    out: Path
    storage: str
    files: list[FileContent]

    @property
    def message_count(self) -> int:
        return sum(len(f.messages) for f in self.files)

    def summary(self) -> str:
        """One line: how many messages from which files."""
        parts = []
        for f in self.files:
            state = "whole" if f.complete else f.problem or "cut off"
            parts.append(f"{f.name} {len(f.messages):,} ({state})")
        return (f"recovered {self.message_count:,} messages from {self.source}: "
                f"{'; '.join(parts)}")


def _natural(path: Path) -> tuple[object, ...]:
    return tuple(int(t) if t.isdigit() else t for t in re.split(r"(\d+)", path.name))


def storage_files(path: Path) -> tuple[str, list[Path]]:
    """The storage and its files, in order, of a bag folder or one file; RecordingError
    with the fix when there is nothing to read."""
    if not path.exists():
        raise RecordingError(f"{path} does not exist; pass a rosbag2 folder or its "
                             ".mcap/.db3 file.")
    files = [path] if path.is_file() else sorted(
        (p for p in path.iterdir() if p.suffix in (".mcap", ".db3") and p.is_file()),
        key=_natural)
    if not files:
        raise RecordingError(f"{path} holds no .mcap or .db3 file; pass the folder the "
                             "recorder wrote (or one of its storage files).")
    kinds = {_kind(f) for f in files}
    if len(kinds) > 1:
        raise RecordingError(f"{path} mixes MCAP and sqlite3 files; pass one of them.")
    return kinds.pop(), files


def _kind(file: Path) -> str:
    try:
        with file.open("rb") as stream:
            head = stream.read(16)
    except OSError as err:
        raise RecordingError(f"cannot read {file} ({err.strerror}); check its "
                             "permissions.") from None
    if not head:
        raise RecordingError(f"{file} is empty: the recorder stopped before writing "
                             "anything, so there is nothing to recover.")
    if head.startswith(MCAP_MAGIC):
        return "mcap"
    if head.startswith(SQLITE_MAGIC):
        return "sqlite3"
    raise RecordingError(f"{file} is neither MCAP nor sqlite3 (its first bytes say "
                         "otherwise); pass a rosbag2 .mcap or .db3 file.")


def read_mcap(file: Path) -> FileContent:
    """Every message of every whole chunk (or unchunked record) before the first damage."""
    content = FileContent(file.name)
    schemas: dict[int, Schema] = {}
    channels: dict[int, int] = {}  # channel id -> topic index
    with file.open("rb") as stream:
        records = StreamReader(stream, emit_chunks=True).records
        try:
            for record in records:
                if isinstance(record, Chunk):
                    inner = breakup_chunk(record, validate_crc=True)
                    _collect(inner, schemas, channels, content)
                elif isinstance(record, Footer):
                    content.complete = True
                else:
                    _collect([record], schemas, channels, content)
        except _CUT as err:
            # A record running past the end is a cut; anything else is damage.
            at_end = isinstance(err, EndOfFile) or stream.tell() >= file.stat().st_size
            content.problem = ("cut off" if at_end
                               else f"damaged: {str(err) or type(err).__name__}")
    return content


def _collect(records: list, schemas: dict[int, Schema], channels: dict[int, int],
             content: FileContent) -> None:
    """Add records in order; a whole chunk is decoded first, so its messages come all
    or none."""
    staged: list[tuple[int, int, bytes]] = []
    for record in records:
        if isinstance(record, Schema):
            schemas[record.id] = record
        elif isinstance(record, Channel):
            schema = schemas.get(record.schema_id)
            if schema is None:
                continue
            content.topics.append(Topic(
                record.topic, schema.name, schema.data.decode(), record.metadata.get(
                    HASH_KEY, ""), record.metadata.get("offered_qos_profiles", "")))
            channels[record.id] = len(content.topics) - 1
        elif isinstance(record, Message) and record.channel_id in channels:
            staged.append((channels[record.channel_id], record.log_time, record.data))
    content.messages.extend(staged)


def read_sqlite(file: Path) -> FileContent:
    """The committed messages of a sqlite3 bag file, its interrupted transaction undone."""
    content = FileContent(file.name)
    with tempfile.TemporaryDirectory(prefix="tactile-recover-") as tmp:
        copy = Path(tmp) / file.name
        shutil.copyfile(file, copy)
        for suffix in ("-journal", "-wal"):
            side = file.with_name(file.name + suffix)
            if side.exists():
                shutil.copyfile(side, copy.with_name(copy.name + suffix))
        try:
            conn = sqlite3.connect(copy)
            try:
                content.complete = bool(conn.execute("SELECT count(*) FROM metadata")
                                        .fetchone()[0])
                defs = {row[0]: (row[1], row[2] or "") for row in conn.execute(
                    "SELECT topic_type, encoded_message_definition, type_description_hash "
                    "FROM message_definitions")}
                ids: dict[int, int] = {}
                for tid, name, msgtype, qos in conn.execute(
                        "SELECT id, name, type, offered_qos_profiles FROM topics ORDER BY id"):
                    msgdef, digest = defs.get(msgtype, ("", ""))
                    content.topics.append(Topic(name, msgtype, msgdef, digest, qos))
                    ids[tid] = len(content.topics) - 1
                content.messages = [
                    (ids[tid], stamp, bytes(data)) for tid, stamp, data in conn.execute(
                        "SELECT topic_id, timestamp, data FROM messages ORDER BY id")
                    if tid in ids]
            finally:
                conn.close()
        except sqlite3.DatabaseError as err:
            if not content.messages:
                raise RecordingError(f"{file} is not a readable rosbag2 sqlite3 file ({err}); "
                                     "pass a .db3 file a recorder wrote.") from None
            content.problem = str(err)
    return content


def read_files(path: Path) -> tuple[str, list[FileContent]]:
    storage, files = storage_files(path)
    reader = read_mcap if storage == "mcap" else read_sqlite
    return storage, [reader(f) for f in files]


@functools.cache
def _typestore() -> object:
    from .bag_writer import default_typestore

    return default_typestore()


def _digest(topic: Topic) -> str:
    """The type hash the file carried, else the one our type store computes (files that
    rosbags wrote carry none in their channels)."""
    if topic.digest:
        return topic.digest
    try:
        return _typestore().hash_rihs01(topic.msgtype)  # type: ignore[attr-defined]
    except Exception:  # an unknown type simply has no hash to offer
        return ""


def _profiles(qos_yaml: str) -> list:
    from rosbags.rosbag2.metadata import parse_qos

    try:
        return parse_qos(qos_yaml) if qos_yaml else []
    except Exception:  # rosbags raises several types on odd text
        return []


def recover(path: Path | str, out: Path | str | None = None) -> Recovery:
    """Write a whole rosbag2 bag at ``out`` (default ``<bag>-recovered`` beside it) from the
    readable part of the bag at ``path``."""
    path = Path(path)
    storage, contents = read_files(path)
    bag = path if path.is_dir() else path.parent
    target = Path(out) if out is not None else bag.with_name(f"{bag.name}-recovered")
    if target.exists():
        raise RecordingError(f"{target} exists already; pass --out naming a new folder.")
    writer = Rosbag2Writer(target, storage, WriterOptions(flush_period_s=float("inf")),
                           custom_data={"recovered_from": str(path)})
    try:
        writer.open()
    except OSError as err:
        raise RecordingError(f"cannot create {target} ({err.strerror}); pass --out naming "
                             "a folder you can write to.") from None
    connections: dict[tuple[str, str], object] = {}
    try:
        for content in contents:
            conns = []
            for topic in content.topics:
                key = (topic.name, topic.msgtype)
                if key not in connections:
                    connections[key] = writer.add_connection(
                        topic.name, topic.msgtype, topic.msgdef, _digest(topic),
                        _profiles(topic.qos_yaml))
                conns.append(connections[key])
            for index, stamp, data in content.messages:
                writer.write(conns[index], stamp, data)  # type: ignore[arg-type]
        writer.close()
    except (OSError, sqlite3.Error) as err:
        writer.abort()
        raise RecordingError(f"writing the recovered bag {target} failed ({err}); free disk "
                             "space or pass another --out.") from None
    return Recovery(path, target, storage, contents)
