"""Ctrl-C and SIGTERM as exceptions, raised once, held back while a run cleans up.

The command line turns SIGINT into KeyboardInterrupt (exit 130) and SIGTERM into Terminated
(exit 143), from its first line (docs/robustness.md, "Supervised processes and signals").
Only the first signal is raised: the ones after it are noted (:func:`received`) while the run
stops, so a second Ctrl-C cannot cut the stop short and leave no summary. Inside
:func:`deferred` a signal is remembered and raised when the block ends (a bag chunk is written
whole); inside :func:`held` it is remembered and never raised: the runner asks
:func:`received` and marks the run interrupted, so that a signal during the stop, the summary
or the teardown still gives a summary that says so.
"""

from __future__ import annotations

import signal
import sys
import threading
from contextlib import contextmanager

EXIT_CODES = {signal.SIGINT: 130, signal.SIGTERM: 143}
SIGNAL_NAMES = {130: "SIGINT", 143: "SIGTERM"}


class Terminated(BaseException):  # like KeyboardInterrupt: no callback guard catches it
    """SIGTERM arrived."""


_raising = 0  # nested raising() blocks
_depth = 0  # nested deferred() / held() blocks
_code: int | None = None  # exit code of the first signal since the outermost raising()
_raised = False  # that signal was raised already


def _raise_for(code: int):
    global _raised
    _raised = True
    if code == EXIT_CODES[signal.SIGINT]:
        raise KeyboardInterrupt
    raise Terminated


def _handler(signum, frame) -> None:
    global _code
    _code = _code or EXIT_CODES[signal.Signals(signum)]
    if not _depth and not _raised:
        _raise_for(_code)


@contextmanager
def raising():
    """SIGINT and SIGTERM raise (KeyboardInterrupt, Terminated) in this block (main thread).

    Also when the process inherited SIGINT ignored, as a script's background job does
    (``activetrack run ... &``): an explicit ``kill -INT`` must stop a run, not be lost."""
    global _raising, _code, _raised
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    if not _raising:
        _code, _raised = None, False
    _raising += 1
    previous = {s: signal.signal(s, _handler) for s in (signal.SIGINT, signal.SIGTERM)}
    hook, sys.unraisablehook = sys.unraisablehook, _quiet_unraisable(sys.unraisablehook)
    try:
        yield
    finally:
        for s, h in previous.items():
            signal.signal(s, h)
        sys.unraisablehook = hook
        _raising -= 1


def _quiet_unraisable(hook):
    """A signal raised inside a finalizer or weakref callback is one Python can only print
    ("Exception ignored in ..."): it is noted already (:func:`received`) and :func:`check`
    raises it again where the run can stop, so it is not printed as a traceback. Nor is the
    AttributeError of a finalizer once a signal came: the signal cut an ``__init__`` short and
    the object's ``__del__`` then misses an attribute (seen: rclpy's ``Task`` without
    ``_exception``, interrupted while the executor made it)."""

    def quiet(unraisable) -> None:
        exc = unraisable.exc_value
        if isinstance(exc, (KeyboardInterrupt, Terminated)):
            return
        finalizer = getattr(unraisable.object, "__name__", "") == "__del__"
        if finalizer and isinstance(exc, AttributeError) and received() is not None:
            return
        hook(unraisable)

    return quiet


@contextmanager
def _holding(raise_at_end: bool):
    global _depth
    _depth += 1
    try:
        yield
    finally:
        _depth -= 1
        if raise_at_end and not _depth and _code is not None and not _raised:
            _raise_for(_code)


def deferred():
    """Signals arriving in this block are raised when it ends (first one wins); inside a
    :func:`held` block they stay noted only."""
    return _holding(raise_at_end=True)


def held():
    """Signals arriving in this block are noted (:func:`received`), never raised."""
    return _holding(raise_at_end=False)


def received() -> int | None:
    """The exit code (130, 143) of the first signal in the outermost :func:`raising` block so
    far, raised or held; None if none came."""
    return _code


def check() -> None:
    """Raise the first signal's exception again if one came: for loops that must stop even
    where the first was swallowed (a C extension that replaced it with its own error, a
    finalizer, whose exceptions Python only prints)."""
    if _code is not None:
        _raise_for(_code)


def exit_code(exc: BaseException) -> int:
    return EXIT_CODES[signal.SIGINT if isinstance(exc, KeyboardInterrupt) else signal.SIGTERM]
