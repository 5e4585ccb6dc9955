"""Rewrite build-machine include paths baked into the ros-jazzy-* wheels' CMake exports.

About a dozen ``share/*/cmake/export_*__rosidl_generator_pyExport.cmake`` files name the
Python and numpy include directories of the machine the wheels were built on
(``/opt/python/cp311-cp311/...``). CMake's generate step rejects non-existent include
directories on imported targets, so building any interface package against them fails.
This replaces them with this interpreter's include directory and ``numpy.get_include()``.
Idempotent: files already rewritten are left alone.

Usage: python tools/fix_ros_wheel_paths.py VENV_PREFIX
"""

import re
import sys
import sysconfig
from pathlib import Path

import numpy

STALE_INCLUDES = re.compile(r'INTERFACE_INCLUDE_DIRECTORIES "([^"]*/opt/python/[^"]*)"')


def main(prefix: str) -> int:
    share = Path(prefix) / "share"
    if not share.is_dir():
        print(f"fix_ros_wheel_paths: no share/ under prefix {prefix!r}", file=sys.stderr)
        return 2
    good = f"{sysconfig.get_paths()['include']};{numpy.get_include()}"
    changed = 0
    for path in share.glob("*/cmake/export_*__rosidl_generator_pyExport.cmake"):
        text = path.read_text()
        new = STALE_INCLUDES.sub(f'INTERFACE_INCLUDE_DIRECTORIES "{good}"', text)
        if new != text:
            path.write_text(new)
            changed += 1
    print(f"fix_ros_wheel_paths: rewrote {changed} CMake export file(s)")
    return 0


if __name__ == "__main__":
    if len(sys.argv) != 2:
        print(__doc__, file=sys.stderr)
        sys.exit(2)
    sys.exit(main(sys.argv[1]))
