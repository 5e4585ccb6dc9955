"""Progress bars of the command line (tqdm), drawn on stderr only when it is a terminal (CI,
pipes and log files get nothing). The library never prints: it calls back with counts, and
:class:`Bar` is such a callback; meanwhile other stderr lines are printed above the bar.
"""

from __future__ import annotations

import contextlib
import io
import sys
from typing import TextIO

from tqdm import tqdm


def on_terminal(stream: TextIO | None = None) -> bool:
    """Whether ``stream`` (default: stderr) is a terminal a bar may be drawn on."""
    stream = sys.stderr if stream is None else stream
    try:
        return stream.isatty()
    except (AttributeError, ValueError):  # no isatty, or closed
        return False


class _AboveTheBar(io.TextIOBase):
    """A stderr stand-in: whole lines go to ``tqdm.write`` (above the bar)."""

    def __init__(self, stream: TextIO):
        self._stream = stream
        self._pending = ""

    def writable(self) -> bool:
        return True

    def write(self, text: str) -> int:
        self._pending += text
        *lines, self._pending = self._pending.split("\n")
        for line in lines:
            tqdm.write(line, file=self._stream)
        return len(text)

    def flush(self) -> None:
        if self._pending:
            tqdm.write(self._pending, file=self._stream)
            self._pending = ""
        self._stream.flush()


class Bar:
    """A progress bar fed with counts, ``bar(done)`` or ``bar(done, total)``; a no-op unless
    ``file`` (default stderr) is a terminal. As a context manager it is removed at the end and
    stderr lines written meanwhile appear above it."""

    def __init__(self, description: str, total: int | None = None, unit: str = "run", file=None):
        self.file = sys.stderr if file is None else file
        self._bar: tqdm | None = None
        self._redirect: contextlib.AbstractContextManager | None = None
        if on_terminal(self.file):
            self._bar = tqdm(total=total, desc=description, unit=unit, file=self.file, leave=False)

    @property
    def shown(self) -> bool:
        return self._bar is not None

    @property
    def done(self) -> int | None:
        """The count the bar shows (None: no bar)."""
        return None if self._bar is None else self._bar.n

    def __call__(self, done: int, total: int | None = None) -> None:
        bar = self._bar
        if bar is None:
            return
        if total is not None and total != bar.total:
            bar.total = total
        if done != bar.n:
            bar.update(done - bar.n)

    def close(self) -> None:
        if self._redirect is not None:
            self._redirect.__exit__(None, None, None)
            self._redirect = None
        if self._bar is not None:
            self._bar.close()
            self._bar = None

    def __enter__(self) -> Bar:
        if self._bar is not None and self.file is sys.stderr:
            self._redirect = contextlib.redirect_stderr(_AboveTheBar(self.file))
            self._redirect.__enter__()
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def epoch_hook(bar: Bar):
    """A ``during_spin(graph)`` hook of :func:`activetrack_bringup.runner.run_graph` that
    feeds ``bar`` with the epochs the run's evaluator has tracked so far."""
    from activetrack_bringup.evaluator import EvaluatorNode

    def during_spin(graph) -> None:
        for node in graph.nodes:
            if isinstance(node, EvaluatorNode):
                bar(max(len(node.tracks) - 1, 0), node.scenario.steps)
                return

    return during_spin
