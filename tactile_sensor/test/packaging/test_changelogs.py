"""Each package's CHANGELOG.rst as ROS release tooling reads it (catkin_pkg's parser, which
bloom and catkin_generate_changelog use): its newest version is the package.xml's and has
entries."""

from __future__ import annotations

from pathlib import Path

import pytest
from catkin_pkg.changelog import get_changelog_from_path
from catkin_pkg.package import parse_package

REPO = Path(__file__).resolve().parents[3]
PACKAGES = [REPO / "tactile_sensor", REPO / "tactile_sensor_interfaces"]


def changelog_problem(package: Path) -> str | None:
    """Why the package's CHANGELOG.rst does not describe its version, or None."""
    parsed = get_changelog_from_path(str(package / "CHANGELOG.rst"))
    # newest first: catkin_pkg iterates versions oldest first unless reversed
    sections = list(parsed.foreach_version(reverse=True)) if parsed is not None else []
    if not sections:
        return f"{package.name}/CHANGELOG.rst has no version section catkin_pkg can read"
    version, _, content = sections[0]
    expected = parse_package(str(package / "package.xml")).version
    if version != expected:
        return f"{package.name}/CHANGELOG.rst starts at {version}, package.xml is {expected}"
    if not str(next(iter(content), "")).strip():
        return f"{package.name}/CHANGELOG.rst has no entries under {version}"
    return None


@pytest.mark.parametrize("package", PACKAGES, ids=[p.name for p in PACKAGES])
def test_the_changelog_starts_at_the_package_version_with_entries(package: Path) -> None:
    assert changelog_problem(package) is None


def test_a_changelog_behind_the_package_version_is_found(tmp_path: Path) -> None:
    (tmp_path / "package.xml").write_text(
        (REPO / "tactile_sensor_interfaces" / "package.xml").read_text()
        .replace("<version>0.2.0</version>", "<version>0.3.0</version>"))
    (tmp_path / "CHANGELOG.rst").write_text(
        (REPO / "tactile_sensor_interfaces" / "CHANGELOG.rst").read_text())
    assert changelog_problem(tmp_path) == (
        f"{tmp_path.name}/CHANGELOG.rst starts at 0.2.0, package.xml is 0.3.0")
