"""``make firmware`` (firmware/build-avr.sh): its refusals, and -Werror biting for real.

The successful cross-build is CI's own step (``.ci/run`` runs ``make firmware``); these
check that a broken sketch or a missing toolchain fails it with one clear sentence.
"""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest

# Runs the AVR toolchain (a process per build).
pytestmark = pytest.mark.slow

REPO = Path(__file__).resolve().parents[3]
SCRIPT = REPO / "firmware" / "build-avr.sh"
has_avr = pytest.mark.skipif(shutil.which("avr-g++") is None,
                             reason="no avr-g++ (apt-get install gcc-avr avr-libc "
                                    "arduino-core-avr)")


def run(tmp_path: Path, **env: str) -> subprocess.CompletedProcess[str]:
    full = {**os.environ, "FIRMWARE_OUT": str(tmp_path / "out"), **env}
    return subprocess.run(["bash", str(SCRIPT)], env=full, capture_output=True, text=True,
                          timeout=300, check=False)


def test_a_missing_toolchain_names_the_packages(tmp_path):
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    for tool in ("bash", "dirname"):
        (bin_dir / tool).symlink_to(shutil.which(tool))
    result = run(tmp_path, PATH=str(bin_dir))
    assert result.returncode == 1
    assert "apt-get install gcc-avr avr-libc arduino-core-avr" in result.stderr


@has_avr
def test_a_missing_core_names_the_package_and_the_override(tmp_path):
    result = run(tmp_path, ARDUINO_AVR_DIR=str(tmp_path))
    assert result.returncode == 1
    assert "arduino-core-avr" in result.stderr and "ARDUINO_AVR_DIR" in result.stderr


@has_avr
@pytest.mark.parametrize(("boards", "sentence"), [
    ("esp32", "unknown board 'esp32'; use uno, nano, mega or leonardo"),
    ("nano:9", "'9' channels for nano; give 1..8"),
], ids=["unknown_board", "channel_count_out_of_range"])
def test_a_board_list_it_cannot_build_is_refused(tmp_path, boards, sentence):
    result = run(tmp_path, FIRMWARE_BOARDS=boards)
    assert result.returncode == 1
    assert sentence in result.stderr


@has_avr
def test_the_eight_channel_nano_image_builds(tmp_path):
    result = run(tmp_path, FIRMWARE_BOARDS="nano", FIRMWARE_CHANNELS="8")
    assert result.returncode == 0, result.stderr
    assert "firmware nano (atmega328p, 8 channel(s))" in result.stdout
    assert (tmp_path / "out" / "nano-8ch" / "tactile_adc.hex").is_file()


@has_avr
def test_more_channels_than_the_uno_has_pins_are_refused(tmp_path):
    result = run(tmp_path, FIRMWARE_BOARDS="uno:8")
    assert result.returncode != 0
    assert "exceeds this board's analog inputs" in result.stderr


@has_avr
def test_a_warning_in_the_sketch_fails_the_build(tmp_path):
    sketch = tmp_path / "tactile_adc.ino"
    source = (REPO / "firmware" / "tactile_adc" / "tactile_adc.ino").read_text()
    sketch.write_text(source.replace("void loop() {", "void loop() {\n  int unused = 0;"))
    result = run(tmp_path, FIRMWARE_SKETCH=str(sketch), FIRMWARE_BOARDS="uno")
    assert result.returncode != 0
    assert "[-Werror=unused-variable]" in result.stderr
