"""The finger's signal chain: ADC codes of its modules -> joint angle and tip force."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from tactile_sensor.sensing.bend_calibration import BendCalibration
from tactile_sensor.sensing.bend_chain import BendChain, BendModule, parse_bend_modules
from tactile_sensor.sensing.chain import ChainConfig
from tactile_sensor.sensing.errors import CalibrationError, SensingError, TareError

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bend_tables import ANGLES, FORCES, table

REST_V = 2.5
VPC = 5.0 / 4095


class Sample:
    def __init__(self, counts, t_us):
        self.counts, self.device_time_us, self.host_time_ns = counts, t_us, t_us * 1000


def counts_for(angle: float, force: float, two: bool = True) -> tuple[int, ...]:
    joint = 0.4 * math.sin(0.9 * angle) + 0.02 * force
    tip = 0.05 * force + 0.01 * force ** 2 + 0.05 * angle
    volts = (REST_V - joint, REST_V - tip) if two else (REST_V - joint,)
    return tuple(round(v / VPC) for v in volts)


def run(chain: BendChain, angle: float, force: float, n: int, start_us: int = 0,
        two: bool = True):
    out = None
    for k in range(n):
        out = chain.process(Sample(counts_for(angle, force, two), start_us + 1000 * k))
    return out


def config() -> ChainConfig:
    return ChainConfig(filter_name="moving_average", filter_params={"window": 5},
                       rest_retare_time_constant_s=0.0)


def test_two_modules_read_angle_and_force_after_the_tare():
    cal = BendCalibration.fit(("joint", "tip"), ANGLES, FORCES, table())
    chain = BendChain(config(), parse_bend_modules("0:joint,1:tip"), cal)
    first = run(chain, 0.0, 0.0, 600)
    assert chain.tared and first.angle_rad == pytest.approx(0.0, abs=0.01)
    r = run(chain, 1.0, 1.5, 50, 600_000)
    assert r.angle_rad == pytest.approx(1.0, abs=math.radians(1.0))
    assert r.force_n == pytest.approx(1.5, abs=0.05)
    assert r.contact and not r.saturated and len(r.outputs_v) == 2


def test_one_module_reads_the_angle_and_nan_force():
    cal = BendCalibration.fit(("joint",), ANGLES, FORCES, table()[:, :, :1])
    chain = BendChain(config(), (BendModule(0, "joint"),), cal)
    run(chain, 0.0, 0.0, 600, two=False)
    r = run(chain, 0.8, 0.0, 50, 600_000, two=False)
    assert r.angle_rad == pytest.approx(0.8, abs=math.radians(1.0))
    assert math.isnan(r.force_n) and not r.contact


def test_an_angle_beyond_the_range_is_nan_and_counted():
    cal = BendCalibration.fit(("joint",), ANGLES, FORCES, table()[:, :, :1])
    chain = BendChain(config(), (BendModule(0, "joint"),), cal)
    run(chain, 0.0, 0.0, 600, two=False)
    for k in range(20):  # the joint output far past its largest
        r = chain.process(Sample((round((REST_V - 0.8) / VPC),), 600_000 + 1000 * k))
    assert math.isnan(r.angle_rad) and r.saturated
    assert chain.out_of_range > 0


def test_untared_and_uncalibrated_read_nan():
    chain = BendChain(config(), parse_bend_modules("0:joint"))
    r = chain.process(Sample(counts_for(0.0, 0.0, False), 0))
    assert math.isnan(r.angle_rad) and math.isnan(r.output_v)
    with pytest.raises(TareError, match="joint"):
        chain.tare()
    run(chain, 0.0, 0.0, 600, two=False)
    assert math.isnan(chain.last.angle_rad) and not math.isnan(chain.last.output_v)


@pytest.mark.parametrize("text, match", [
    ("0:tip", "module over the joint"),
    ("", "module over the joint"),
    ("0:knuckle", "CHANNEL:PLACE"),
    ("9:joint", "channel"),
    ("0:joint,0:tip", "repeats"),
])
def test_bad_layouts_are_refused_in_one_sentence(text, match):
    with pytest.raises(SensingError, match=match) as info:
        parse_bend_modules(text)
    assert str(info.value).replace("e.g.", "").count(". ") == 0


def test_a_calibration_for_other_modules_is_refused():
    cal = BendCalibration.fit(("joint", "tip"), ANGLES, FORCES, table())
    chain = BendChain(config(), parse_bend_modules("0:joint"))
    with pytest.raises(CalibrationError, match="fit one for these modules"):
        chain.set_calibration(cal)


def test_a_missing_channel_is_named():
    chain = BendChain(config(), parse_bend_modules("0:joint,3:tip"))
    with pytest.raises(SensingError, match="channel 3"):
        chain.process(Sample((100, 100), 0))
    assert np.isfinite(chain.top_channel)
