"""The launch files and configurations are consistent: every executable they name is
installed, every file they load exists, every argument is declared and used, and every
parameter in a config file is one its node declares (rclpy would silently ignore a typo).
The files run for real with ``ros2 launch`` in test_ros2_launch_*.py."""

from __future__ import annotations

import ast
import importlib
import os
import re
from pathlib import Path

import pytest
import yaml

from tactile_sensor.configurations import CONFIGURATIONS, config_dir, config_files

PACKAGE_DIR = Path(__file__).resolve().parents[2]
LAUNCH_DIR = PACKAGE_DIR / "launch"
BUILDER = PACKAGE_DIR / "tactile_sensor" / "launch_description.py"


def installed_prefix() -> Path:
    for prefix in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep):
        if (Path(prefix) / "share" / "tactile_sensor" / "package.xml").exists():
            return Path(prefix)
    pytest.fail("tactile_sensor is not installed: run 'make setup' (colcon build) and "
                ". scripts/env.sh")


def node_parameter_names(module: str, node_class: str) -> set[str]:
    """Names the node class declares (its module-level ParamSpec lists)."""
    mod = importlib.import_module(module)
    names = {"autostart"}
    for value in vars(mod).values():
        if isinstance(value, list) and value and hasattr(value[0], "validate"):
            names |= {spec.name for spec in value}
    if "physics_specs" in vars(mod):
        names |= {spec.name for spec in mod.physics_specs()}
    return names


def test_each_configuration_has_its_launch_file_built_from_it():
    for name in CONFIGURATIONS:
        source = (LAUNCH_DIR / f"{name}.launch.py").read_text()
        assert f"build({name.upper()})" in source
        assert "generate_launch_description" in source


def test_every_executable_named_is_installed_where_ros2_run_looks():
    lib = installed_prefix() / "lib" / "tactile_sensor"
    executables = {spec.executable for c in CONFIGURATIONS.values() for spec in c.nodes}
    executables |= set(re.findall(r'executable="(\w+)"', BUILDER.read_text()))
    for executable in executables:
        assert (lib / executable).is_file(), f"{executable} missing in {lib}"
        assert os.access(lib / executable, os.X_OK)
    assert (lib / "tactile-sensor").is_file()


def test_every_file_loaded_exists_in_source_and_install():
    share = installed_prefix() / "share" / "tactile_sensor"
    files = {f for c in CONFIGURATIONS.values() for spec in c.nodes
             for f in config_files(spec, use_mock=True)}
    files.add("protocols.yaml")
    for name in files:
        assert (config_dir() / name).is_file(), name
        assert (share / "config" / name).is_file(), f"{name} not installed"
    for launch in LAUNCH_DIR.glob("*.launch.py"):
        assert (share / "launch" / launch.name).is_file(), f"{launch.name} not installed"


def _launch_arguments() -> tuple[set[str], set[str]]:
    tree = ast.parse(BUILDER.read_text())
    declared, used = set(), set()
    for call in ast.walk(tree):
        if isinstance(call, ast.Call) and isinstance(call.func, ast.Name) and call.args \
                and isinstance(call.args[0], ast.Constant):
            if call.func.id == "DeclareLaunchArgument":
                declared.add(call.args[0].value)
            elif call.func.id == "LaunchConfiguration":
                used.add(call.args[0].value)
    return declared, used


def test_every_launch_argument_is_declared_and_used():
    declared, used = _launch_arguments()
    assert declared == used, (declared, used)
    assert {"use_mock_hardware", "config", "namespace", "record", "protocol"} <= declared
    # port arguments are declared and used through the configuration's ports table
    source = BUILDER.read_text()
    assert "configuration.ports.items()" in source and "for name in configuration.ports" in source
    for configuration in CONFIGURATIONS.values():
        port_args = set(configuration.ports)
        referenced = {arg for spec in configuration.nodes for _, arg in spec.port_parameters}
        assert referenced == port_args, (configuration.name, referenced, port_args)


def _sections(path: Path) -> dict[str, dict]:
    data = yaml.safe_load(path.read_text()) or {}
    return {key: value.get("ros__parameters", {}) for key, value in data.items()}


def test_every_config_parameter_is_declared_by_its_node():
    for configuration in CONFIGURATIONS.values():
        for spec in configuration.nodes:
            declared = node_parameter_names(spec.module, spec.node_class)
            for name in config_files(spec, use_mock=True):
                for key, params in _sections(config_dir() / name).items():
                    target = key.rsplit("/", 1)[-1]
                    if target not in ("**", spec.name):
                        continue
                    if target == "**":  # shared section: only keys this node knows apply
                        continue
                    unknown = set(params) - declared
                    assert not unknown, f"{name} [{key}] undeclared for {spec.name}: {unknown}"


def test_the_gripper_file_states_the_gripper_nodes_defaults():
    """config/gripper.yaml lists the gripper's parameters with their defaults, for a user
    to edit. A default changed in the node but not in the file would give every bringup and
    launch the old value while the benchmarks measure the new one (settle_time once stayed
    1 s there after the node's default became 1.5 s)."""
    from tactile_sensor.nodes.gripper_parameters import SPECS
    defaults = {spec.name: spec.default for spec in SPECS}
    stated = _sections(config_dir() / "gripper.yaml")["/**/gripper"]
    differ = {name: (value, defaults[name]) for name, value in stated.items()
              if name in defaults and value != defaults[name]}
    assert not differ, f"config/gripper.yaml (file, node default): {differ}"


def test_shared_sections_are_declared_by_some_node_of_the_configuration():
    for configuration in CONFIGURATIONS.values():
        declared = set().union(*(node_parameter_names(s.module, s.node_class)
                                 for s in configuration.nodes))
        for spec in configuration.nodes:
            for name in config_files(spec, use_mock=True):
                shared = _sections(config_dir() / name).get("/**", {})
                assert set(shared) <= declared, (name, set(shared) - declared)


def test_protocols_only_set_parameters_of_the_mock_rig():
    table = yaml.safe_load((config_dir() / "protocols.yaml").read_text())
    bench = CONFIGURATIONS["bench"].nodes[0]
    declared = node_parameter_names(bench.module, bench.node_class)
    for section in ("bench", "array"):
        for name, params in table[section].items():
            assert set(params) <= declared, (section, name, set(params) - declared)
    for name, params in table["gripper"].items():
        assert all(key.startswith("protocol.") for key in params or {}), name


def test_mock_only_files_load_with_mock_hardware_only():
    gripper = next(s for s in CONFIGURATIONS["gripper"].nodes if s.name == "gripper")
    real, mock = config_files(gripper, use_mock=False), config_files(gripper, use_mock=True)
    assert "gripper_mock.yaml" in mock and "gripper_mock.yaml" not in real
    assert mock[:len(real)] == real  # after the real settings, so they win over them
    patient = _sections(config_dir() / "gripper_mock.yaml")["/**/gripper"]
    default = _sections(config_dir() / "gripper.yaml")["/**/gripper"]
    for name in ("packet_timeout", "tactile_timeout"):
        assert patient[name] > default[name], name
