"""Every import of the package is covered by a package.xml key, and every key is used.

A dependency that is imported but not declared is the robot-install bug found late: rosdep
installs nothing for it and the node dies on import. One declared but never imported is the
other half (python3-mcap-pip once broke `rosdep install` for nothing).
"""

from __future__ import annotations

import ast
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[2]
INTERFACES = PACKAGE.parent / "tactile_sensor_interfaces"

# Import name -> the rosdep key (or ROS package) that provides it.
PROVIDER = {
    "rclpy": "rclpy",
    "geometry_msgs": "geometry_msgs",
    "sensor_msgs": "sensor_msgs",
    "std_msgs": "std_msgs",
    "std_srvs": "std_srvs",
    "builtin_interfaces": "builtin_interfaces",
    "diagnostic_msgs": "diagnostic_msgs",
    "lifecycle_msgs": "lifecycle_msgs",
    "rcl_interfaces": "rcl_interfaces",
    "control_msgs": "control_msgs",
    "tactile_sensor_interfaces": "tactile_sensor_interfaces",
    "launch": "launch",
    "launch_ros": "launch_ros",
    "numpy": "python3-numpy",
    "scipy": "python3-scipy",
    "serial": "python3-serial",
    "yaml": "python3-yaml",
    "matplotlib": "python3-matplotlib",
    "rosbags": "python3-rosbags-pip",
    "skfem": "python3-scikit-fem-pip",
    "dynamixel_sdk": "python3-dynamixel-sdk-pip",
    "dynamixel_easy_sdk": "python3-dynamixel-sdk-pip",
    "apsw": "python3-apsw-pip",
    "dask": "python3-dask-pip",
    "distributed": "python3-distributed-pip",
    "mcap": "python3-mcap-pip",
    "ruamel": "python3-ruamel.yaml",
    "catkin_pkg": "python3-catkin-pkg",
    "pytest": "python3-pytest",
    "hypothesis": "python3-hypothesis",
    "xdist": "python3-pytest-xdist",
    "action_msgs": "action_msgs",
    "xacro": "xacro",
    "urdf_parser_py": "urdfdom_py",
}
# the package, and the tests' own helper modules (beside conftest.py, and interface_servers)
FIRST_PARTY = {"tactile_sensor", "interface_servers"} | {
    path.stem for path in Path(__file__).resolve().parents[1].glob("*.py")}


def third_party_imports(*roots: Path) -> dict[str, Path]:
    """Top-level module -> one file importing it, over every .py under the roots."""
    found: dict[str, Path] = {}
    for root in roots:
        for path in sorted(root.rglob("*.py")):
            for node in ast.walk(ast.parse(path.read_text(), str(path))):
                if isinstance(node, ast.Import):
                    names = [alias.name for alias in node.names]
                elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                    names = [node.module]
                else:
                    continue
                for name in names:
                    top = name.split(".")[0]
                    if top not in sys.stdlib_module_names and top not in FIRST_PARTY:
                        found.setdefault(top, path)
    return found


def declared(package_dir: Path, *tags: str) -> set[str]:
    root = ET.parse(package_dir / "package.xml").getroot()
    return {element.text.strip() for tag in tags for element in root.iter(tag)}


def _uncovered(imports: dict[str, Path], keys: set[str]) -> list[str]:
    return [
        f"{module} (imported in {path.name}): "
        + (f"declare {PROVIDER[module]}" if module in PROVIDER else "add it to PROVIDER")
        for module, path in sorted(imports.items())
        if PROVIDER.get(module) not in keys
    ]


def test_every_runtime_import_is_an_exec_dependency() -> None:
    runtime = third_party_imports(PACKAGE / "tactile_sensor", PACKAGE / "launch")
    assert _uncovered(runtime, declared(PACKAGE, "exec_depend", "depend")) == []


def test_every_test_import_is_a_declared_dependency() -> None:
    tests = third_party_imports(PACKAGE / "test")
    keys = declared(PACKAGE, "exec_depend", "depend", "test_depend")
    assert _uncovered(tests, keys) == []


def test_every_declared_key_is_imported() -> None:
    used = {
        PROVIDER[module]
        for module in third_party_imports(PACKAGE / "tactile_sensor", PACKAGE / "launch",
                                          PACKAGE / "test")
        if module in PROVIDER
    }
    keys = declared(PACKAGE, "exec_depend", "depend", "test_depend")
    assert sorted(keys - used) == []


def test_interface_definitions_use_declared_packages() -> None:
    used = set()
    for path in INTERFACES.glob("*/*.*"):
        if path.suffix in {".msg", ".srv", ".action"}:
            for line in path.read_text().splitlines():
                field_type = line.split("#")[0].split()[:1]
                if field_type and "/" in field_type[0]:
                    used.add(field_type[0].split("/")[0])
    assert used, "no interface definitions found"
    assert sorted(used - declared(INTERFACES, "depend", "build_depend")) == []


def test_the_scanner_sees_an_undeclared_import(tmp_path: Path) -> None:
    (tmp_path / "node.py").write_text("import os\nimport numpy\nfrom lxml import etree\n"
                                      "from . import sibling\n")
    imports = third_party_imports(tmp_path)
    assert set(imports) == {"numpy", "lxml"}
    problems = _uncovered(imports, {"python3-numpy"})
    assert len(problems) == 1 and problems[0].startswith("lxml") and "PROVIDER" in problems[0]
