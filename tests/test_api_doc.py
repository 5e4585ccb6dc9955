"""docs/api.md works as written: its python blocks run, top to bottom, as one script."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "api.md"


def python_blocks(text: str) -> list[str]:
    return re.findall(r"^```python\n(.*?)^```", text, flags=re.S | re.M)


def test_the_documented_snippets_run():
    blocks = python_blocks(DOC.read_text())
    assert len(blocks) >= 4
    script = "\n".join(blocks)
    # The first block is the notebook one-liner of the issue: load, run_batch with jobs.
    assert "at.run_batch(sc, runs=20, jobs=2)" in blocks[0]
    out = subprocess.run(
        [sys.executable, "-c", script],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    assert out.returncode == 0, out.stderr[-3000:]
    m = re.search(r"20 runs x 30 epochs: RMSE x ([\d.]+) m, PCRLB x ([\d.]+) m", out.stdout)
    assert m, out.stdout
    rmse, bound = float(m[1]), float(m[2])
    # A PF tracking a target the planner steers towards: the RMSE sits at the bound or
    # above it, and within a factor of two (default scenario, 20 runs).
    assert 0.8 * bound <= rmse <= 2.0 * bound
