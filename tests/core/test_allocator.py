"""The glibc allocator tuning applied on `import activetrack` (activetrack.allocator)."""

import os
import subprocess
import sys

import pytest

CHECK = "import activetrack.allocator as a, activetrack; print(a._applied)"


def _run(env_overrides):
    env = {k: v for k, v in os.environ.items() if not k.startswith("MALLOC_")}
    env.pop("ACTIVETRACK_MALLOC_TUNING", None)
    env.update(env_overrides)
    out = subprocess.run([sys.executable, "-c", CHECK], env=env, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    return out.stdout.strip()


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc only")
def test_applied_on_import_unless_switched_off_or_user_set():
    assert _run({}) == "True"
    assert _run({"ACTIVETRACK_MALLOC_TUNING": "0"}) == "False"
    assert _run({"MALLOC_ARENA_MAX": "2"}) == "False"  # the user's MALLOC_* settings win
