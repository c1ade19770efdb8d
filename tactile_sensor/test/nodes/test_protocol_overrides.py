"""``--protocol NAME:key=value,...``: overrides typed like the YAML value they replace, and
one sentence for an override that cannot be read (pure; no ROS)."""

from __future__ import annotations

import pytest

from tactile_sensor.nodes.bringup import BringupError, protocol_parameters


def test_overrides_replace_the_protocols_fields_with_their_types():
    base = protocol_parameters("bench", "speeds")
    short = protocol_parameters("bench", "speeds:cycles=1, rest=0.5,speeds=0.001/0.01")
    assert short["protocol.name"] == "speeds"
    assert short["protocol.cycles"] == 1 and isinstance(short["protocol.cycles"], int)
    assert short["protocol.rest"] == 0.5
    assert short["protocol.speeds"] == [0.001, 0.01]
    assert short["protocol.depth"] == base["protocol.depth"]


def test_the_ambient_protocol_takes_its_scenario_as_an_override():
    assert protocol_parameters("bench", "ambient")["protocol.scenario"] == "office"
    sun = protocol_parameters("bench", "ambient:scenario=sunlight,cycles=1")
    assert (sun["protocol.scenario"], sun["protocol.cycles"]) == ("sunlight", 1)


@pytest.mark.parametrize("spec, fragment", [
    ("speeds:cycles", "Cannot read 'cycles'"),           # no '='
    ("speeds:colour=red", "keys depth, speeds, cycles"),  # unknown key names the known ones
    ("speeds:name=x", "Cannot read 'name=x'"),            # the name is not a field
    ("speeds:cycles=two", "not a number of the kind 'cycles' takes"),
    ("speeds:cycles=1.5", "not a number of the kind 'cycles' takes"),
    ("speeds:speeds=0.001/fast", "not a number of the kind 'speeds' takes"),
    ("sideways:cycles=1", "Unknown bench protocol 'sideways'"),
])
def test_an_unreadable_override_is_one_sentence(spec, fragment):
    with pytest.raises(BringupError, match=fragment):
        protocol_parameters("bench", spec)
