"""A user's YAML file read with one sentence for each way it can be wrong.

The model's ``--config`` and a study's SPEC fail alike (unreadable, not UTF-8, bad syntax),
so both commands name the problem and its fix the same way.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any


def read_yaml(path: Path, what: str, error: type[Exception], example: str = "") -> Any:
    """The data of the YAML file ``path``; ``error`` naming ``what`` it is (e.g. "the
    config file") and the fix (``example``: where to find a good one) when it cannot be."""
    import yaml

    try:
        text = path.read_text(encoding="utf-8")
    except OSError as err:
        raise error(f"cannot read {what} {path} ({err.strerror}); pass an existing YAML "
                    f"file{example}.") from None
    except UnicodeDecodeError:
        raise error(f"{what} {path} is not UTF-8 text; pass a YAML file.") from None
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None)
        where = f" at line {mark.line + 1}" if mark is not None else ""
        raise error(f"{what} {path} is not valid YAML{where}; fix its syntax.") from None
