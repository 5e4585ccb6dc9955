"""The glibc allocator tuning (activetrack.allocator): opt-in, and importing the core changes no
process-wide setting."""

import os
import subprocess
import sys

import pytest

TUNE = "import activetrack.allocator as a; a.tune_allocator(); print(a._applied)"

# Everything process-wide a library could touch on import, before and after importing every
# module of the core.
UNTOUCHED = """
import importlib, locale, os, pkgutil, signal, sys, warnings
import numpy as np
def state():
    return (
        dict(os.environ), {s: signal.getsignal(s) for s in signal.valid_signals()
                           if s not in (signal.SIGKILL, signal.SIGSTOP)},
        np.geterr(), np.get_printoptions(), list(warnings.filters),
        sys.getrecursionlimit(), locale.setlocale(locale.LC_ALL), sys.getswitchinterval(),
    )
before = state()
import activetrack, activetrack.allocator as a
for m in pkgutil.walk_packages(activetrack.__path__, "activetrack."):
    importlib.import_module(m.name)
print(before == state(), a._applied)
"""


def _run(code, env_overrides=None):
    env = {k: v for k, v in os.environ.items() if not k.startswith("MALLOC_")}
    env.pop("ACTIVETRACK_MALLOC_TUNING", None)
    env.update(env_overrides or {})
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    return out.stdout.strip()


def test_importing_the_core_changes_no_process_wide_setting():
    assert _run(UNTOUCHED) == "True None"  # and the allocator was not touched


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc only")
def test_tuning_is_opt_in_and_yields_to_the_user():
    assert _run(TUNE) == "True"
    assert _run(TUNE, {"ACTIVETRACK_MALLOC_TUNING": "0"}) == "False"
    assert _run(TUNE, {"MALLOC_ARENA_MAX": "2"}) == "False"  # the user's MALLOC_* settings win


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc only")
def test_a_variable_set_by_dask_does_not_block_the_tuning_once_named():
    """A Dask worker's MALLOC_TRIM_THRESHOLD_ (its nanny's default): refused until the Monte
    Carlo task names it as not the user's (activetrack.montecarlo.dask)."""
    code = (
        "import activetrack.allocator as a; print(a.tune_allocator()); "
        "print(a.tune_allocator(ignore=('MALLOC_TRIM_THRESHOLD_',)), a.allocator_tuned())"
    )
    assert _run(code, {"MALLOC_TRIM_THRESHOLD_": "65536"}).split() == ["False", "True", "True"]
