"""Ambient light as the detector sees it: the level, the lamp's flicker with its harmonics,
switching steps through the detector's response, and the scenarios refused."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tactile_sensor.physics.detector import DetectorState, response_tau_s
from tactile_sensor.sim.ambient_light import (
    LightScene,
    LitSource,
    parse_steps,
    scenario_scene,
)
from tactile_sensor.sim.errors import SimError


def test_a_lamp_flickers_at_its_frequency_around_its_mean_ratio():
    scene = LightScene(flicker_ratio=0.2, flicker_hz=100.0, sample_rate_hz=1000.0)
    t = np.arange(0.0, 1.0, 1e-5)
    ratio = scene.ratio(t)
    assert ratio.mean() == pytest.approx(0.2, rel=1e-3)
    assert ratio.min() >= 0.0 and ratio.max() < 0.2 * math.pi / 2
    spectrum = np.abs(np.fft.rfft(ratio - ratio.mean()))
    freqs = np.fft.rfftfreq(t.size, 1e-5)
    assert freqs[np.argmax(spectrum)] == pytest.approx(100.0)
    second = spectrum[np.argmin(np.abs(freqs - 200.0))]
    assert 0.1 * spectrum.max() < second < 0.5 * spectrum.max()  # a harmonic, weaker


def test_a_step_settles_with_the_detectors_response_and_steps_add_up():
    scene = LightScene(dc_ratio=0.1, steps=parse_steps(["2:-0.1", "1:0.3"]))
    tau = response_tau_s()
    assert scene.steps == ((1.0, 0.3), (2.0, -0.1))
    got = scene.ratio(np.array([0.999, 1.0 + tau, 1.0 + 10 * tau, 3.0]))
    assert got == pytest.approx([0.1, 0.1 + 0.3 * (1 - math.exp(-1)), 0.4, 0.3], abs=1e-4)


def test_the_dark_room_leaves_the_worlds_voltages_untouched():
    volts = np.array([[1.9], [1.5]])
    lit = LitSource(lambda t: volts, LightScene(), DetectorState(), [1.99])
    assert lit(np.zeros(2)) is volts


def test_a_lit_source_darkens_each_module_and_keeps_the_sources_revision():
    class Source:
        revision = 7

        def __call__(self, t):
            return np.tile([[2.0, 3.0]], (len(t), 1))

    lit = LitSource(Source(), LightScene(dc_ratio=0.1), DetectorState(), [2.0, 3.0])
    out = lit(np.zeros(3))
    assert out.shape == (3, 2) and lit.revision == 7
    assert out[0] == pytest.approx([2.0 - 0.3, 3.0 - 0.2], abs=1e-6)


@pytest.mark.parametrize(("kwargs", "sentence"), [
    ({"dc_ratio": -0.1}, "ambient.dc_ratio = -0.1 is negative"),
    ({"flicker_ratio": -0.2}, "ambient.flicker_ratio = -0.2 is negative"),
    ({"flicker_ratio": 0.2, "flicker_hz": 600.0}, "Nyquist rate 500 Hz"),
    ({"dc_ratio": float("nan")}, "ambient.dc_ratio = nan must be a finite number"),
    ({"steps": ((1.0, float("inf")),)}, "must be a finite number"),
    ({"dc_ratio": 0.1, "steps": ((1.0, -0.3),)}, "negative ratio (-0.2) at 1 s"),
])
def test_an_impossible_scene_is_refused_in_one_sentence(kwargs, sentence):
    with pytest.raises(SimError) as error:
        LightScene(sample_rate_hz=1000.0, **kwargs)
    assert sentence in str(error.value) and "\n" not in str(error.value)


@pytest.mark.parametrize("item", ["5", "a:0.3", "5:x", ""])
def test_a_step_that_is_not_time_ratio_is_refused(item):
    with pytest.raises(SimError, match="is not 'time:ratio'"):
        parse_steps([item])


def test_the_scenarios_of_the_ambient_protocol_in_protocol_seconds():
    office = scenario_scene("office", 0.56, 1000.0)
    assert office.steps == ((2.5, 0.3), (12.5, -0.3)) and office.flicker_ratio == 0.2
    assert scenario_scene("sunlight", 0.56, 1000.0).dc_ratio == pytest.approx(0.336)
    assert scenario_scene("dark", 0.56, 1000.0).is_dark
    shadow = scenario_scene("shadow", 0.56, 1000.0)
    assert shadow.ratio(np.array([15.0, 16.5, 17.5])) == pytest.approx([0.3, 0.1, 0.3],
                                                                       abs=1e-6)
    with pytest.raises(SimError, match="Unknown ambient scenario 'fog'; choose one of dark"):
        scenario_scene("fog", 0.56, 1000.0)


def test_steps_count_from_the_protocols_start_and_none_come_before_it():
    class Protocol:
        start_device_s: float | None = None

        def __call__(self, t):
            return np.full((len(t), 1), 2.0)

    source = Protocol()
    lit = LitSource(source, LightScene(steps=((1.0, 0.5),)), DetectorState(), [2.0])
    assert lit(np.array([100.0]))[0, 0] == pytest.approx(2.0)  # not started: no step
    source.start_device_s = 100.0
    assert lit(np.array([100.5, 102.0]))[:, 0] == pytest.approx([2.0, 2.0 - 1.5], abs=1e-6)
    fixed = LitSource(source, LightScene(steps=((1.0, 0.5),)), DetectorState(), [2.0],
                      origin_s=5.0)
    assert fixed(np.array([5.5, 7.0]))[:, 0] == pytest.approx([2.0, 0.5], abs=1e-6)
