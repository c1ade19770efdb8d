"""Control table data: addresses agree with the SDK's own XM430-W210 model file."""

from __future__ import annotations

from pathlib import Path

import dynamixel_easy_sdk
import pytest
from hypothesis import given
from hypothesis import strategies as st

from tactile_sensor.hardware import xm430_table as table


def sdk_table() -> dict[str, tuple[int, int]]:
    path = Path(dynamixel_easy_sdk.__file__).parent / "control_table" / "xm430_w210.model"
    lines = path.read_text().splitlines()
    start = lines.index("[control table]") + 2
    out = {}
    for line in lines[start:]:
        parts = line.split("\t")
        if len(parts) == 3 and parts[0].isdigit():
            out[parts[2]] = (int(parts[0]), int(parts[1]))
    return out


def test_every_item_matches_the_sdk_model_file():
    reference = sdk_table()
    for item in table.ITEMS:
        assert reference[item.name] == (item.address, item.size), item.name


def test_items_do_not_overlap_and_initials_are_in_range():
    ends = 0
    for item in sorted(table.ITEMS, key=lambda i: i.address):
        assert item.address >= ends
        ends = item.end
        assert item.minimum <= item.initial <= item.maximum, item.name


def test_units():
    assert pytest.approx(2 * 3.141592653589793) == table.RAD_PER_PULSE * 4096
    assert pytest.approx(0.229 * 0.10471975511965977) == table.RAD_S_PER_VELOCITY_UNIT
    assert pytest.approx(2.69e-3) == table.A_PER_CURRENT_UNIT


@given(st.integers(0, 255))
def test_hardware_error_codec_round_trips(value):
    assert table.encode_hardware_error(table.decode_hardware_error(value)) == value


def test_hardware_error_names():
    assert table.decode_hardware_error(0x21) == {"input_voltage", "overload"}
    assert table.decode_hardware_error(0x1C) == {"overheating", "motor_encoder",
                                                 "electrical_shock"}


def test_unknown_names_are_rejected():
    with pytest.raises(ValueError, match="unknown hardware error"):
        table.encode_hardware_error({"melted"})
    with pytest.raises(KeyError, match="no control-table item"):
        table.item("Goal Torque")


@given(st.integers(-2**31, 2**31 - 1))
def test_signed_items_round_trip(value):
    item = table.item("Present Position")
    assert item.from_bytes(item.to_bytes(value)) == value
