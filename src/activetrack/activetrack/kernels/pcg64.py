"""numpy's PCG64 stream and its ziggurat normals inside compiled kernels: the bits of
``Generator.standard_normal`` for ``numpy.random.default_rng`` generators, without a call into
numpy per draw.

The particle filter's process noise (4 normals per particle and step) is the largest part of a
compiled PF step. numba's own ``Generator`` support calls the bit generator through a function
pointer per draw and costs about 9 us per kernel call to unbox the generator; here:

- **the stream**: PCG64 is a 128-bit LCG, s_{k+1} = a s_k + c (mod 2^128), whose output is the
  XSL-RR mix of the new state. :func:`refill` steps it in LANES (16) interleaved chains,
  s_{k+16} = a^16 s_k + c (a^15 + ... + a + 1), in 512-bit vectors (``pcg64_lanes``), into a
  small buffer (16 KiB, cache-resident) that the kernel consumes and refills as it goes;
- **the normals**: numpy's ziggurat on those outputs (:func:`layer` for the ~99 % accepted at
  once, :func:`rejected` for the rest, with numpy's 256-layer tables as numba ships them); one
  output per normal except after a rejection;
- **the generator**: read with :func:`stream_words` and advanced by the outputs used with
  :func:`advance` (numpy's public ``state`` and ``advance``, under the generator's lock; a
  buffered 32-bit half survives).

:func:`pcg64_route` says whether a generator takes this route: a plain ``PCG64`` bit generator,
and the route checked once per process against numpy itself (the caller's kernel is compared
with numpy's draws; a mismatch warns and leaves numba's generic route in use). The rejection
branches use ``np.exp`` / ``np.log1p`` as numba's own implementation does; tests/core/
test_pf_kernels.py compares millions of draws with numpy bit for bit.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from typing import Any

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic
from numba.np.random._constants import (
    fi_double,
    ki_double,
    wi_double,
    ziggurat_nor_inv_r,
    ziggurat_nor_r,
)

from activetrack.kernels.pcg64_lanes import LANES, step_lanes

__all__ = [
    "BUFFER",
    "KI",
    "advance",
    "layer",
    "new_stream",
    "pcg64_route",
    "refill",
    "rejected",
    "stream_words",
]

_MASK64 = (1 << 64) - 1
_MOD128 = 1 << 128
_A = (0x2360ED051FC65DA4 << 64) | 0x4385DF649FCCF645  # PCG64's multiplier (numpy's)
_AL = pow(_A, LANES, _MOD128)
_KL = sum(pow(_A, k, _MOD128) for k in range(LANES)) % _MOD128  # c K is the LANES-step increment
# uint64 halves (hi, lo) of a, a^LANES and K for the compiled code.
_HALVES = np.array([v >> s & _MASK64 for v in (_A, _AL, _KL) for s in (64, 0)], dtype=np.uint64)
# The ziggurat's tables indexed by an output's low 9 bits, key = sign bit << 8 | layer: the
# layer's rectangle bound KI and its width WI with the sign folded in (x = rabs * -WI is -(rabs *
# WI) exactly: rounding is symmetric), so a draw needs no sign step and one index.
_KI = np.array(ki_double, dtype=np.uint64)
KI = np.concatenate([_KI, _KI])
_WI = np.array(wi_double, dtype=np.float64)
_WS = np.concatenate([_WI, -_WI])
_FI = np.array(fi_double, dtype=np.float64)
_TO_UNIT = 1.0 / 9007199254740992.0  # 2^-53: PCG64's next_double from a 64-bit output
BUFFER = 2048  # raw outputs per refill (a multiple of LANES: whole rounds of the chains)


def _mul_add_128_typing(typingctx, hi, lo, ahi, alo, chi, clo):  # pragma: no cover - compiled
    """(hi, lo) * (ahi, alo) + (chi, clo) mod 2^128, each number as two uint64 halves;
    returns (hi, lo). LLVM's i128 arithmetic: one 64 x 64 -> 128 product, two 64-bit ones."""
    u64 = types.uint64
    sig = types.UniTuple(u64, 2)(u64, u64, u64, u64, u64, u64)

    def codegen(context, builder, signature, args):
        i128, i64 = ir.IntType(128), ir.IntType(64)
        shift = ir.Constant(i128, 64)

        def join(h, low):
            return builder.or_(builder.shl(builder.zext(h, i128), shift), builder.zext(low, i128))

        s = builder.add(builder.mul(join(*args[0:2]), join(*args[2:4])), join(*args[4:6]))
        halves = [builder.trunc(builder.lshr(s, shift), i64), builder.trunc(s, i64)]
        return context.make_tuple(builder, signature.return_type, halves)

    return sig, codegen


_mul_add_128: Any = intrinsic(_mul_add_128_typing)  # called from compiled code only


@njit(cache=True)
def new_stream(words):  # pragma: no cover - compiled
    """The LANES chains after state ``words`` = (s_hi, s_lo, c_hi, c_lo): a uint64 array for
    :func:`refill` (``pcg64_lanes``' layout: the chains' states s_1..s_LANES as high halves,
    then low halves, then a^LANES and c K as hi, lo pairs)."""
    a_hi, a_lo = _HALVES[0], _HALVES[1]
    c_hi, c_lo = words[2], words[3]
    chains = np.empty(2 * LANES + 4, dtype=np.uint64)
    h, low = words[0], words[1]
    for k in range(LANES):
        h, low = _mul_add_128(h, low, a_hi, a_lo, c_hi, c_lo)
        chains[k], chains[LANES + k] = h, low
    zero = np.uint64(0)
    chains[2 * LANES], chains[2 * LANES + 1] = _HALVES[2], _HALVES[3]
    hi, lo = _mul_add_128(c_hi, c_lo, _HALVES[4], _HALVES[5], zero, zero)
    chains[2 * LANES + 2], chains[2 * LANES + 3] = hi, lo
    return chains


@njit(cache=True)
def refill(chains, buf, start):  # pragma: no cover - compiled
    """Write the stream's next outputs into buf[start:], whole rounds of the LANES chains
    (``len(buf) - start`` rounded down to a multiple of LANES); returns the end of the data."""
    rounds = (buf.shape[0] - start) // LANES
    step_lanes(chains, buf, start, rounds)
    return start + rounds * LANES


@njit(inline="always")
def layer(r):  # pragma: no cover - compiled
    """numpy's ziggurat split of a 64-bit output: (key, |x| bits, x on the layer) with key the
    low 9 bits (layer = key & 0xFF, then the sign bit); x is the normal when |x| bits <
    KI[key] (about 99 % of draws), else see :func:`rejected`."""
    key = r & np.uint64(0x1FF)
    rabs = (r >> np.uint64(9)) & np.uint64(0x000FFFFFFFFFFFFF)
    # rabs < 2^52: exact as a signed integer; the sign is the table's (no branch: a random
    # sign mispredicts half the time).
    x = np.float64(np.int64(rabs)) * _WS[key]
    return key, rabs, x


@njit(cache=True)
def rejected(raw, j, end, key, rabs, x):  # pragma: no cover - compiled
    """numpy's ziggurat after a first output outside its layer's rectangle (``key``, ``rabs``,
    ``x`` of :func:`layer`): the tail (layer 0) or the wedge test, then new outputs until one
    is accepted, reading raw[j:end]. Returns (x, next j), or (nan, -1) when the data runs out
    first."""
    while True:
        idx = key & np.uint64(0xFF)
        if idx == 0:
            while True:
                if j + 2 > end:
                    return math.nan, -1
                xx = -ziggurat_nor_inv_r * np.log1p(-((raw[j] >> np.uint64(11)) * _TO_UNIT))
                yy = -np.log1p(-((raw[j + 1] >> np.uint64(11)) * _TO_UNIT))
                j += 2
                if yy + yy > xx * xx:
                    if (rabs >> np.uint64(8)) & np.uint64(1):
                        return -(ziggurat_nor_r + xx), j
                    return ziggurat_nor_r + xx, j
        if j + 2 > end:
            return math.nan, -1
        u = (raw[j] >> np.uint64(11)) * _TO_UNIT
        if (_FI[idx - 1] - _FI[idx]) * u + _FI[idx] < np.exp(-0.5 * x * x):
            return x, j + 1
        key, rabs, x = layer(raw[j + 1])
        j += 2
        if rabs < KI[key]:
            return x, j


def stream_words(rng: np.random.Generator) -> tuple[np.ndarray, dict[str, Any]]:
    """``(words, state)``: the PCG64 state and increment as uint64 halves (s_hi, s_lo, c_hi,
    c_lo), and numpy's state dict (for :func:`advance`). Call under ``rng.bit_generator.lock``."""
    state: dict[str, Any] = rng.bit_generator.state  # type: ignore[assignment]
    s, c = state["state"]["state"], state["state"]["inc"]
    words = np.array([s >> 64, s & _MASK64, c >> 64, c & _MASK64], dtype=np.uint64)
    return words, state


def advance(rng: np.random.Generator, used: int, state: dict[str, Any]) -> None:
    """Move ``rng`` past ``used`` outputs of the stream read with :func:`stream_words`, as
    numpy's own draws would (``advance`` drops a buffered 32-bit half: it is put back)."""
    bg: Any = rng.bit_generator  # a PCG64 (pcg64_route)
    bg.advance(used)
    if state["has_uint32"]:
        after = dict(bg.state)
        after["has_uint32"], after["uinteger"] = state["has_uint32"], state["uinteger"]
        bg.state = after


_checked: dict[str, bool] = {}
_check_lock = threading.Lock()


def pcg64_route(rng: np.random.Generator, name: str, check: Callable[[], bool]) -> bool:
    """Whether ``rng`` takes the PCG64 route for the kernel ``name``: a plain PCG64 bit
    generator, and ``check()`` (the kernel against numpy's own draws, run once per process)
    passed. A failed check warns once and the caller keeps its generic route."""
    if type(rng.bit_generator) is not np.random.PCG64:
        return False
    ok = _checked.get(name)
    if ok is None:
        with _check_lock:
            ok = _checked[name] = bool(check())
        if not ok:
            import warnings

            warnings.warn(
                f"activetrack.kernels.pcg64: {name} does not reproduce this numpy's draws on "
                "the PCG64 route; numba's generator route is used instead",
                RuntimeWarning,
                stacklevel=3,
            )
    return ok


def warm_up() -> None:
    """Compile (or load from the disk cache) the stream's kernels."""
    chains = new_stream(np.zeros(4, dtype=np.uint64))
    buf = np.empty(BUFFER, dtype=np.uint64)
    refill(chains, buf, 0)
    key, rabs, x = np.uint64(0), np.uint64(0), 0.0
    rejected(buf, 0, buf.shape[0], key, rabs, x)
