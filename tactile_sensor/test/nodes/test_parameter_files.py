"""A user's parameter file with a name no node declares is refused in one sentence naming
the closest declared name, by the bringup and by the launch files alike."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from tactile_sensor.configurations import CONFIGURATIONS, config_dir
from tactile_sensor.nodes import bringup
from tactile_sensor.nodes.parameter_files import (
    ParameterFileError,
    check_parameter_file,
    declared_parameters,
    flatten,
)

BENCH = CONFIGURATIONS["bench"]


def write(tmp_path: Path, data: object) -> Path:
    path = tmp_path / "extra.yaml"
    path.write_text(yaml.safe_dump(data) if not isinstance(data, str) else data)
    return path


@pytest.fixture(scope="module")
def declared() -> dict[str, frozenset[str]]:
    return declared_parameters(BENCH)


@pytest.mark.parametrize(("section", "name", "closest"), [
    ("/**/bench", "noise.whit", "noise.white"),
    ("/**", "noise.whit", "noise.white"),
    ("driver", "filter_typ", "filter_type"),
    ("/**/driver", "contact_on_forse", "contact_on_force"),
])
def test_a_typo_is_refused_naming_the_closest_declared_parameter(
        tmp_path, declared, section, name, closest):
    path = write(tmp_path, {section: {"ros__parameters": {name: 0.01}}})
    with pytest.raises(ParameterFileError) as error:
        check_parameter_file(path, BENCH, declared)
    message = str(error.value)
    assert f"sets '{name}'" in message and f"did you mean '{closest}'?" in message
    assert message.count(".") >= 1 and "\n" not in message


def test_a_nested_typo_is_found_under_its_dotted_name(tmp_path, declared):
    path = write(tmp_path, {"/**/bench": {"ros__parameters": {"noise": {"whit": 0.01}}}})
    with pytest.raises(ParameterFileError, match=r"'noise.whit'.*'noise.white'"):
        check_parameter_file(path, BENCH, declared)


def test_a_section_for_a_node_the_configuration_lacks_names_the_closest_node(
        tmp_path, declared):
    path = write(tmp_path, {"/**/drivr": {"ros__parameters": {"channel": 1}}})
    with pytest.raises(ParameterFileError, match=r"node '/\*\*/drivr'.*did you mean 'driver'"):
        check_parameter_file(path, BENCH, declared)


def test_a_parameter_of_another_node_is_refused_in_a_named_section(tmp_path, declared):
    path = write(tmp_path, {"driver": {"ros__parameters": {"noise.white": 0.01}}})
    with pytest.raises(ParameterFileError, match=r"node 'driver' does not declare"):
        check_parameter_file(path, BENCH, declared)


def test_a_name_far_from_every_declared_one_points_to_the_reference(tmp_path, declared):
    path = write(tmp_path, {"/**": {"ros__parameters": {"zzzzzzzzzzzz": 1}}})
    with pytest.raises(ParameterFileError, match=r"see docs/reference"):
        check_parameter_file(path, BENCH, declared)


@pytest.mark.parametrize("text", ["a: [1, 2", "- 1\n- 2\n", "driver: 3\n"])
def test_a_file_that_is_no_parameter_file_is_refused(tmp_path, declared, text):
    with pytest.raises(ParameterFileError, match=r"YAML|ROS parameter file"):
        check_parameter_file(write(tmp_path, text), BENCH, declared)


@pytest.mark.parametrize("name", sorted(CONFIGURATIONS))
def test_the_shipped_files_pass_for_every_configuration(name):
    configuration = CONFIGURATIONS[name]
    declared = declared_parameters(configuration)
    files = {f for spec in configuration.nodes for f in spec.config_files
             + spec.mock_config_files}
    for file in files:
        check_parameter_file(config_dir() / file, configuration, declared)


def test_good_names_pass_in_every_section_form(tmp_path, declared):
    path = write(tmp_path, {"/**": {"ros__parameters": {"use_sim_time": False}},
                            "/robot/bench": {"ros__parameters": {"noise": {"white": 0.01}}},
                            "driver": {"ros__parameters": {"channel": 1}},
                            "/*/model": {"ros__parameters": {}}})
    check_parameter_file(path, BENCH, declared)
    assert flatten({"a": {"b": 1, "c": {"d": 2}}, "e": 3}) == ["a.b", "a.c.d", "e"]


def test_bringup_refuses_a_typo_in_one_sentence_and_starts_nothing(tmp_path, capsys):
    path = write(tmp_path, {"/**": {"ros__parameters": {"noise.whit": 0.01}}})
    assert bringup.main(["bench", "--config", str(path), "--duration", "1"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("tactile-sensor bringup: ") and err.count("\n") == 1
    assert "'noise.whit'" in err and "did you mean 'noise.white'?" in err


@pytest.mark.ros2_tools
def test_the_launch_files_refuse_a_typo_before_starting_a_node(tmp_path):
    """As ``ros2 launch tactile_sensor bench.launch.py config:=FILE`` builds it: every
    argument the launch file declares at its default, only ``config`` given, so the context
    never lags an argument added to the launch file. Under the real ``ros2 launch``:
    test_ros2_launch_errors.py."""
    from launch import LaunchContext
    from launch.actions import DeclareLaunchArgument

    from tactile_sensor import launch_description as ld

    path = write(tmp_path, {"/**/bench": {"ros__parameters": {"noise.whit": 0.01}}})
    context = LaunchContext()
    context.launch_configurations["config"] = str(path)
    for action in ld.build(BENCH).entities:
        if isinstance(action, DeclareLaunchArgument):
            action.visit(context)  # its default, unless given
    with pytest.raises(ld.LaunchArgumentError, match=r"did you mean 'noise.white'"):
        ld._nodes(context, BENCH, ld._protocols(BENCH))
