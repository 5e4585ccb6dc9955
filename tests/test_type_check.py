"""The core library type-checks: mypy (pinned in constraints.txt) with the configuration of the
root pyproject.toml ([tool.mypy]: the whole of src/activetrack/activetrack), so `make test`
runs the type checker."""

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def test_core_passes_mypy():
    pytest.importorskip("mypy", reason="mypy is pinned in requirements.txt; run make setup")
    proc = subprocess.run(
        [sys.executable, "-m", "mypy", "--no-error-summary", "--config-file", "pyproject.toml"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=600,
    )
    errors = (proc.stdout + proc.stderr).strip()
    assert proc.returncode == 0, f"mypy found type errors:\n{errors}"


def test_the_package_is_marked_typed():
    """PEP 561: py.typed ships with the package, so its users' type checkers read the hints."""
    core = ROOT / "src" / "activetrack"
    assert (core / "activetrack" / "py.typed").is_file()
    assert "py.typed" in (core / "pyproject.toml").read_text()
