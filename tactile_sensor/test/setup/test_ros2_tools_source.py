"""Where setup finds the ros2 tools' sources, including a real clone from a local repository."""

from __future__ import annotations

import importlib.util
import subprocess
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[3] / "scripts" / "ros2_tools_source.py"
_spec = importlib.util.spec_from_file_location("ros2_tools_source", SCRIPT)
tools = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(tools)


def _git(cwd: Path, *args: str) -> str:
    return subprocess.run(["git", *args], cwd=cwd, check=True, capture_output=True,
                          text=True).stdout.strip()


@pytest.fixture
def upstream(tmp_path: Path) -> tuple[Path, str]:
    """A git repository holding one kept package (launch) and one other (launch_testing)."""
    repo = tmp_path / "upstream"
    for name in ("launch", "launch_testing"):
        (repo / name).mkdir(parents=True)
        (repo / name / "package.xml").write_text(f"<package><name>{name}</name></package>")
    _git(repo, "init", "-q")
    _git(repo, "-c", "user.name=t", "-c", "user.email=t@t", "add", ".")
    _git(repo, "-c", "user.name=t", "-c", "user.email=t@t", "commit", "-qm", "one")
    _git(repo, "config", "uploadpack.allowReachableSHA1InWant", "true")
    return repo, _git(repo, "rev-parse", "HEAD")


def _repos_file(path: Path, url: str, commit: str) -> Path:
    path.write_text(f"repositories:\n  launch:\n    type: git\n    url: {url}\n"
                    f"    version: {commit}\n")
    return path


def test_configured_folder_wins(tmp_path: Path) -> None:
    assert tools.find_source(tmp_path, {"ROS2_TOOLS_SRC": str(tmp_path)}) == tmp_path


def test_configured_folder_missing_is_one_sentence(tmp_path: Path) -> None:
    with pytest.raises(tools.SourceError, match=r"ROS2_TOOLS_SRC=.*is not a folder"):
        tools.find_source(tmp_path, {"ROS2_TOOLS_SRC": str(tmp_path / "nope")})


def test_shared_folder_beside_the_repository(tmp_path: Path) -> None:
    root = tmp_path / "main"
    (root / "requirements").mkdir(parents=True)
    (tmp_path / "shared" / "ros2-src").mkdir(parents=True)
    assert tools.find_source(root, {}) == tmp_path / "shared" / "ros2-src"


def test_clone_at_the_pinned_commit_ignores_other_packages(tmp_path: Path, upstream) -> None:
    repo, commit = upstream
    root = tmp_path / "main"
    (root / "requirements").mkdir(parents=True)
    _repos_file(root / "requirements" / "ros2-tools.repos", f"file://{repo}", commit)
    src = tools.find_source(root, {})
    assert (src / "launch" / "launch" / "package.xml").is_file()
    assert not (src / "launch" / "launch" / "COLCON_IGNORE").exists()
    assert (src / "launch" / "launch_testing" / "COLCON_IGNORE").is_file()
    # Reused while the commit is unchanged: a second call needs no repository at all.
    _repos_file(root / "requirements" / "ros2-tools.repos", "file:///nonexistent", commit)
    assert tools.find_source(root, {}) == src


def test_unreachable_repository_is_one_sentence(tmp_path: Path) -> None:
    root = tmp_path / "main"
    (root / "requirements").mkdir(parents=True)
    _repos_file(root / "requirements" / "ros2-tools.repos", f"file://{tmp_path}/none", "0" * 40)
    with pytest.raises(tools.SourceError, match="git fetch failed"):
        tools.find_source(root, {})


def test_unreadable_repos_file_is_one_sentence(tmp_path: Path) -> None:
    root = tmp_path / "main"
    (root / "requirements").mkdir(parents=True)
    (root / "requirements" / "ros2-tools.repos").write_text("repositories: [")
    with pytest.raises(tools.SourceError, match="not a readable vcstool repos file"):
        tools.find_source(root, {})


def test_main_prints_the_folder_or_one_line(tmp_path: Path, capsys, monkeypatch) -> None:
    monkeypatch.setenv("ROS2_TOOLS_SRC", str(tmp_path))
    assert tools.main(["x", str(tmp_path)]) == 0
    assert capsys.readouterr().out.strip() == str(tmp_path)
    monkeypatch.setenv("ROS2_TOOLS_SRC", str(tmp_path / "missing"))
    assert tools.main(["x", str(tmp_path)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "is not a folder" in err[0]
