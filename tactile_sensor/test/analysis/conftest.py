"""What the analysis tests share: running `tactile-sensor analyze` and judging its refusal."""

from __future__ import annotations

from collections.abc import Callable

import pytest

from tactile_sensor.analysis import cli


def _run(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    code = cli.main([*argv, "--quiet"])
    return code, capsys.readouterr().err


def _assert_one_sentence(code: int, err: str, *fragments: str) -> None:
    assert code == 1
    assert "Traceback" not in err
    lines = [x for x in err.splitlines() if x.strip()]
    assert len(lines) == 1, err
    for fragment in fragments:
        assert fragment in lines[0]


@pytest.fixture
def run() -> Callable[[list[str], pytest.CaptureFixture[str]], tuple[int, str]]:
    """`tactile-sensor analyze ARGV --quiet`: (exit code, what it wrote to stderr)."""
    return _run


@pytest.fixture
def assert_one_sentence() -> Callable[..., None]:
    """A refusal: exit code 1 and one line on stderr, without a traceback, holding every
    fragment."""
    return _assert_one_sentence
