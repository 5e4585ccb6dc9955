"""One line on the machine a benchmark ran on: its CPU and the SIMD level numpy uses there.

Timings depend on the host more than on the load: on this project's 2-core VMs, a host whose
CPU has AVX-512 ran both our steps and Stone Soup's about three times as fast as one without
(numpy's exp, arcsin and friends are vectorised there), so every figure is quoted with this line.
"""

from __future__ import annotations

import os
import platform


def cpu_model() -> str:
    """The CPU's model name (``/proc/cpuinfo``; the platform's processor string elsewhere)."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def numpy_simd() -> str:
    """The widest SIMD extension numpy dispatches to on this CPU (AVX512_SKX, AVX2, ...)."""
    try:
        from numpy._core._multiarray_umath import __cpu_features__ as features
    except ImportError:  # numpy < 2
        from numpy.core._multiarray_umath import __cpu_features__ as features
    for name in ("AVX512_SPR", "AVX512_ICL", "AVX512_SKX", "AVX512F", "AVX2", "SSE42", "ASIMD"):
        if features.get(name):
            return name
    return "baseline"


def describe() -> str:
    """``cpu <model>, numpy SIMD <level>, <n> cores, load average <x>``."""
    return (
        f"cpu {cpu_model()}, numpy SIMD {numpy_simd()}, {os.cpu_count()} cores, "
        f"load average {os.getloadavg()[0]:.1f}"
    )


if __name__ == "__main__":
    print(describe())
