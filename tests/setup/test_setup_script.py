"""The set-up is idempotent and names the step that failed."""

import os
import stat
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SETUP = ROOT / "tools" / "setup.sh"

pytestmark = pytest.mark.skipif(
    not (ROOT / ".venv" / ".activetrack-stamps").is_dir(), reason="needs a set-up workspace"
)


def _run(env_extra=None):
    env = {k: v for k, v in os.environ.items() if k != "_ROS_WHEELS_BOOTSTRAP_COMPLETE"}
    env.update(env_extra or {})
    return subprocess.run(
        ["bash", str(SETUP)], capture_output=True, text=True, env=env, check=False
    )


def test_second_run_skips_every_step():
    out = _run()
    assert out.returncode == 0, out.stderr
    for step in ("python-packages", "msgs_defs", "editable-packages"):
        assert f"[{step}] unchanged, skipped" in out.stdout


def test_broken_step_fails_loudly_with_its_name(tmp_path):
    fake = tmp_path / "python3"
    fake.write_text("#!/bin/sh\nexit 1\n")
    fake.chmod(fake.stat().st_mode | stat.S_IEXEC)
    out = _run({"PYTHON": str(fake)})
    assert out.returncode != 0
    assert "FAILED in step 'venv'" in out.stderr
