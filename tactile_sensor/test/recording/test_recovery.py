"""``tactile-sensor bag recover``: every whole chunk of a cut MCAP file comes back, in a
bag the mcap library and rosbags read; every bad input gets one sentence and exit 1."""

from __future__ import annotations

import os
import shutil
import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from mcap.reader import make_reader
from rosbags.rosbag2 import Reader

from tactile_sensor.recording import RecordingError, default_typestore
from tactile_sensor.recording.cli import main as bag_main
from tactile_sensor.recording.recovery import recover
from tactile_sensor.recording.rosbag2_writer import Rosbag2Writer, WriterOptions

WRENCH = "geometry_msgs/msg/WrenchStamped"
TYPESTORE = default_typestore()
MSGDEF, _ = TYPESTORE.generate_msgdef(WRENCH, ros_version=2)
DIGEST = TYPESTORE.hash_rihs01(WRENCH)
PER_CHUNK = 25
CHUNKS = 12


def payload(i: int) -> bytes:
    return i.to_bytes(4, "little") * (10 + i % 7)  # raw bytes: recovery never decodes them


class Source(tuple):
    """(file bytes, [(file size after chunk, messages so far)]), with a short repr for
    hypothesis' failure report."""

    def __repr__(self) -> str:
        return f"Source({len(self[0])} bytes, {len(self[1])} chunks)"


@pytest.fixture(scope="module")
def cut_source(tmp_path_factory) -> Source:
    """A one-file MCAP bag flushed every PER_CHUNK messages: its bytes, and per chunk
    (file size after it, messages so far)."""
    folder = tmp_path_factory.mktemp("source") / "bag"
    writer = Rosbag2Writer(folder, "mcap", WriterOptions(flush_period_s=float("inf")))
    writer.open()
    conn = writer.add_connection("/w", WRENCH, MSGDEF, DIGEST)
    ends = []
    for i in range(PER_CHUNK * CHUNKS):
        writer.write(conn, 1_000_000 + i, payload(i))
        if i % PER_CHUNK == PER_CHUNK - 1:
            writer.flush()
            ends.append(((folder / "bag_0.mcap").stat().st_size, i + 1))
    writer.close()
    return Source(((folder / "bag_0.mcap").read_bytes(), ends))


@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(fraction=st.floats(0.0, 1.0))
def test_a_file_cut_anywhere_gives_back_every_whole_chunk(cut_source, tmp_path_factory,
                                                          fraction):
    data, ends = cut_source
    cut = 8 + int(fraction * (len(data) - 8))
    folder = tmp_path_factory.mktemp("cut") / "bag"
    folder.mkdir()
    (folder / "bag_0.mcap").write_bytes(data[:cut])
    out = folder.with_name("recovered")
    result = recover(folder, out)
    whole = max([n for end, n in ends if end <= cut], default=0)
    # every chunk that ended before the cut, and at most the one whose index the cut split
    assert whole <= result.message_count <= whole + PER_CHUNK
    if cut == len(data):
        assert result.message_count == PER_CHUNK * CHUNKS and result.files[0].complete
    with (out / "recovered_0.mcap").open("rb") as stream:
        reader = make_reader(stream)
        got = [(m.log_time, m.data) for _, _, m in reader.iter_messages()]
    assert got == [(1_000_000 + i, payload(i)) for i in range(result.message_count)]
    with Reader(out) as bag:
        assert bag.message_count == result.message_count
        if result.message_count:
            assert [c.digest for c in bag.connections] == [DIGEST]


def test_a_killed_sqlite3_writer_leaves_its_commits(tmp_path):
    writer = Rosbag2Writer(tmp_path / "bag", "sqlite3", WriterOptions(flush_period_s=1e9))
    writer.open()
    conn = writer.add_connection("/w", WRENCH, MSGDEF, DIGEST)
    for i in range(3000):
        writer.write(conn, i, payload(i))
        if i == 1999:
            writer.flush()
    shutil.copytree(tmp_path / "bag", tmp_path / "killed")  # open transaction, no metadata
    writer.abort()
    result = recover(tmp_path / "killed", tmp_path / "recovered")
    assert result.message_count == 2000
    with Reader(tmp_path / "recovered") as bag:
        assert [stamp for _, stamp, _ in bag.messages()] == list(range(2000))


def test_the_cli_recovers_beside_the_bag_and_says_what_it_found(cut_source, tmp_path, capsys):
    data, ends = cut_source
    folder = tmp_path / "run"
    folder.mkdir()
    (folder / "run_0.mcap").write_bytes(data[:ends[3][0] + 5])
    assert bag_main(["recover", str(folder)]) == 0
    out = capsys.readouterr().out
    assert "recovered 100 messages" in out and "run_0.mcap 100 (cut off)" in out
    assert (tmp_path / "run-recovered" / "metadata.yaml").is_file()


@pytest.mark.slow
def test_the_tactile_sensor_command_dispatches_bag_recover(tmp_path):
    (tmp_path / "bag").mkdir()
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[2])}
    result = subprocess.run([sys.executable, "-m", "tactile_sensor.cli", "bag", "recover",
                             str(tmp_path / "bag")], capture_output=True, text=True,
                            timeout=60, env=env)
    assert result.returncode == 1
    assert result.stderr.strip().endswith("(or one of its storage files).")
    assert "Traceback" not in result.stderr


def _empty_folder(tmp: Path) -> Path:
    (tmp / "bag").mkdir()
    (tmp / "bag" / "notes.txt").write_text("no bag here")
    return tmp / "bag"


def _not_mcap(tmp: Path) -> Path:
    (tmp / "x.mcap").write_text("this is plain text, not MCAP")
    return tmp / "x.mcap"


def _empty_file(tmp: Path) -> Path:
    (tmp / "bag").mkdir()
    (tmp / "bag" / "bag_0.mcap").write_bytes(b"")
    return tmp / "bag"


def _corrupt_db(tmp: Path) -> Path:
    (tmp / "bad.db3").write_bytes(b"SQLite format 3\x00" + b"\xff" * 200)
    return tmp / "bad.db3"


def _not_a_bag_db(tmp: Path) -> Path:
    sqlite3.connect(tmp / "other.db3").execute("CREATE TABLE t(x)").connection.commit()
    return tmp / "other.db3"


@pytest.mark.parametrize(("make", "fragment"), [
    (lambda tmp: tmp / "missing", "does not exist"),
    (_empty_folder, "holds no .mcap or .db3 file"),
    (_not_mcap, "is neither MCAP nor sqlite3"),
    (_empty_file, "is empty"),
    (_corrupt_db, "not a readable rosbag2 sqlite3 file"),
    (_not_a_bag_db, "not a readable rosbag2 sqlite3 file"),
])
def test_bad_input_gives_one_sentence_and_exit_1(tmp_path, capsys, make, fragment):
    assert bag_main(["recover", str(make(tmp_path))]) == 1
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and fragment in lines[0] and "Traceback" not in err


def test_an_existing_output_folder_is_refused(cut_source, tmp_path):
    (tmp_path / "bag").mkdir()
    (tmp_path / "bag" / "bag_0.mcap").write_bytes(cut_source[0])
    (tmp_path / "out").mkdir()
    with pytest.raises(RecordingError, match="exists already; pass --out"):
        recover(tmp_path / "bag", tmp_path / "out")


def test_an_unwritable_output_folder_is_refused(cut_source, tmp_path):
    (tmp_path / "bag").mkdir()
    (tmp_path / "bag" / "bag_0.mcap").write_bytes(cut_source[0])
    (tmp_path / "file").write_text("")
    with pytest.raises(RecordingError, match=r"cannot create .*pass --out"):
        recover(tmp_path / "bag", tmp_path / "file" / "out")
