"""Ctrl-C and SIGTERM as exceptions, held back while a run cleans up.

The command line turns SIGINT into KeyboardInterrupt (exit 130) and SIGTERM into Terminated
(exit 143). Inside :func:`deferred` a signal is remembered instead of raised and raised when
the block ends, so the bag is closed and the summary written first.
"""

from __future__ import annotations

import signal
import threading
from contextlib import contextmanager

EXIT_CODES = {signal.SIGINT: 130, signal.SIGTERM: 143}


class Terminated(BaseException):  # like KeyboardInterrupt: no callback guard catches it
    """SIGTERM arrived."""


_defer = 0
_pending: int | None = None


def _raise_for(signum: int):
    if signum == signal.SIGINT:
        raise KeyboardInterrupt
    raise Terminated


def _handler(signum, frame) -> None:
    global _pending
    if _defer:
        _pending = _pending or signum
        return
    _raise_for(signum)


@contextmanager
def raising():
    """SIGINT and SIGTERM raise (KeyboardInterrupt, Terminated) in this block (main thread)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {}
    for s in (signal.SIGINT, signal.SIGTERM):
        if signal.getsignal(s) is not signal.SIG_IGN:  # e.g. SIGINT of a background job
            previous[s] = signal.signal(s, _handler)
    try:
        yield
    finally:
        for s, h in previous.items():
            signal.signal(s, h)


@contextmanager
def deferred():
    """Signals arriving in this block are raised when it ends (first one wins)."""
    global _defer, _pending
    _defer += 1
    try:
        yield
    finally:
        _defer -= 1
        if not _defer and _pending is not None:
            signum, _pending = _pending, None
            _raise_for(signum)


def exit_code(exc: BaseException) -> int:
    return EXIT_CODES[signal.SIGINT if isinstance(exc, KeyboardInterrupt) else signal.SIGTERM]
