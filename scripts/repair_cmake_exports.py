"""Point the ROS wheels' CMake exports at this interpreter.

The PyPI ROS 2 wheels are built in a manylinux image; their
``*rosidl_generator_pyExport.cmake`` files name that image's Python and NumPy
include directories, which do not exist here, so generating Python bindings for
our own interfaces would fail. Rewrite them to this interpreter's paths.
Idempotent: files already pointing here are left alone.
"""

from __future__ import annotations

import sys
import sysconfig
from pathlib import Path

import numpy

BROKEN = {
    "/opt/python/cp311-cp311/lib/python3.11/site-packages/numpy/_core/include": numpy.get_include(),
    "/opt/python/cp311-cp311/include/python3.11": sysconfig.get_paths()["include"],
}


def main() -> int:
    prefix = Path(sys.prefix)
    changed = 0
    for path in prefix.glob("share/*/cmake/*rosidl_generator_pyExport.cmake"):
        text = path.read_text()
        fixed = text
        for old, new in BROKEN.items():
            fixed = fixed.replace(old, new)
        if fixed != text:
            path.write_text(fixed)
            changed += 1
    print(f"repair_cmake_exports: {changed} file(s) rewritten under {prefix}/share")
    return 0


if __name__ == "__main__":
    sys.exit(main())
