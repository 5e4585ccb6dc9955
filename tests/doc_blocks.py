"""The code blocks of a doc page, for the tests that check or run them (docs/extending.md).

Every fenced block of such a page is marked on the line before it::

    <!-- file my_sensors.py, checked against tests/core/test_extending_sensor.py -->
    ```python
    ...
    ```

``checked against`` names what the block must equal (tests/core/test_extending_docs.py):
a test file (its Python statements), a test file and a constant (a YAML scenario), or "the
command line" (commands the ``activetrack`` parser accepts). ``file NAME`` gives the block a
name by which tests take its text and run it, e.g. as a plugin module written to a temporary
folder.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
EXTENDING = ROOT / "docs" / "extending.md"

_MARKED = re.compile(
    r"^(?P<indent>[ ]*)<!-- (?:file (?P<file>\S+), )?checked against (?P<against>.+?) -->\n"
    r"(?:[ ]*\n)*(?P=indent)```(?P<lang>\w+)\n(?P<code>.*?)\n(?P=indent)```[ ]*$",
    re.M | re.S,
)
_FENCE = re.compile(r"^[ ]*```\w+", re.M)


@dataclass(frozen=True)
class Block:
    lang: str  # the fence's language: python, yaml, console
    code: str  # the block's text, its indentation in the page removed
    against: str  # what it is checked against
    file: str | None  # its name, if tests take it by name
    line: int  # line of the marker in the page


def blocks(page: Path = EXTENDING) -> list[Block]:
    """The marked blocks of ``page``, in order."""
    text = page.read_text()
    out = []
    for m in _MARKED.finditer(text):
        indent = m["indent"]
        lines = [line.removeprefix(indent) for line in m["code"].split("\n")]
        line = text.count("\n", 0, m.start()) + 1
        out.append(Block(m["lang"], "\n".join(lines) + "\n", m["against"], m["file"], line))
    return out


def fences(page: Path = EXTENDING) -> int:
    """Opening fences (with a language) in ``page``: every one must be marked."""
    return len(_FENCE.findall(page.read_text()))


def file_block(name: str, page: Path = EXTENDING) -> str:
    """The text of the block named ``file NAME``."""
    found = [b.code for b in blocks(page) if b.file == name]
    if len(found) != 1:
        raise LookupError(f"{page} has {len(found)} blocks named {name!r}")
    return found[0]
