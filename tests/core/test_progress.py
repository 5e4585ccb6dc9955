"""Progress: the library calls back with counts and never prints; the command line draws a
tqdm bar from the callbacks on a terminal only. The numbers never depend on it.
"""

from __future__ import annotations

import io
import sys

import numpy as np
import pytest

import activetrack as at
from activetrack.montecarlo import TaskProgress, parallel_map
from activetrack_bringup.cli import main as cli_main
from activetrack_bringup.progress import Bar, on_terminal
from activetrack_experiments import valverde, vanderhook

SCENARIO = "scenarios/default.yaml"


def _square(x: int) -> int:
    return x * x


class Calls(list):
    def __call__(self, *counts):
        self.append(counts if len(counts) > 1 else counts[0])


@pytest.mark.parametrize("jobs", [1, 2])
def test_parallel_map_reports_every_task_in_order(jobs):
    calls = Calls()
    tasks = list(range(11))
    assert parallel_map(_square, tasks, jobs, progress=calls) == parallel_map(_square, tasks, jobs)
    assert calls == list(range(1, 12))


def test_task_progress_adds_up_parts():
    calls = Calls()
    tasks = TaskProgress(1 + 3 + 2, calls)
    tasks.advance()
    parallel_map(_square, range(3), 1, tasks.of_map())
    parallel_map(_square, range(2), 1, tasks.of_map())
    assert calls == [(1, 6), (2, 6), (3, 6), (4, 6), (5, 6), (6, 6)]
    silent = TaskProgress(3, None)
    assert silent.of_map() is None
    silent.advance()  # no callback, no error


@pytest.fixture(scope="module")
def scenario():
    return at.load_scenario(SCENARIO).model_copy(update={"steps": 5})


def test_run_batch_same_numbers_with_progress(scenario):
    calls = Calls()
    with_bar = at.run_batch(scenario, runs=3, jobs=2, progress=calls)
    plain = at.run_batch(scenario, runs=3, jobs=2)
    assert calls == [1, 2, 3]
    np.testing.assert_array_equal(with_bar.rmse_t, plain.rmse_t)
    np.testing.assert_array_equal(with_bar.bound_t, plain.bound_t)
    for a, b in zip(with_bar.records, plain.records, strict=True):
        np.testing.assert_array_equal(a.track_series()[0], b.track_series()[0])


def test_reproductions_same_numbers_with_progress():
    calls = Calls()
    kw = dict(runs=2, steps=4, noise_pairs=[(0.1, 0.01)])
    with_bar = valverde.reproduce(**kw, task_progress=calls)
    plain = valverde.reproduce(**kw)
    assert with_bar.to_json()["rows"] == plain.to_json()["rows"]
    total = len(plain.rows)
    assert calls == [(d, total) for d in range(1, total + 1)]

    calls = Calls()
    kw = dict(runs=3, betas=[0.1])
    with_bar = vanderhook.reproduce(**kw, task_progress=calls)
    assert with_bar.to_json() == vanderhook.reproduce(**kw).to_json()
    total = calls[-1][1]
    assert calls == [(d, total) for d in range(1, total + 1)]


class FakeTerminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_bar_is_drawn_on_a_terminal_only():
    term = FakeTerminal()
    with Bar("batch", total=4, file=term) as bar:
        assert bar.shown
        for done in (1, 2, 3, 4):
            bar(done)
        assert bar.done == 4
    # drawn (tqdm redraws at most every 0.1 s, so the first state is what is sure to show),
    # then removed: the command's own output follows on a clean line
    assert "batch:   0%" in term.getvalue() and "0/4" in term.getvalue()
    assert term.getvalue().endswith("\r")

    pipe = io.StringIO()
    with Bar("batch", total=4, file=pipe) as bar:
        assert not bar.shown
        bar(1)
        assert bar.done is None
    assert pipe.getvalue() == ""
    assert not on_terminal(pipe) and on_terminal(term)


def test_cli_prints_no_bar_when_stderr_is_not_a_terminal(capsys, tmp_path):
    path = tmp_path / "short.yaml"
    path.write_text(open(SCENARIO).read().replace("steps: 30", "steps: 3"))
    assert cli_main(["batch", str(path), "--runs", "2"]) == 0
    out = capsys.readouterr()
    assert "RMSE" in out.out
    assert out.err == ""  # no bar, no carriage returns: CI logs and pipes stay clean


def test_lines_written_meanwhile_go_above_the_bar(monkeypatch):
    term = FakeTerminal()
    monkeypatch.setattr(sys, "stderr", term)
    with Bar("reproduce hernandez", total=2, unit="task") as bar:
        bar(1)
        print("[hernandez] 1 sensor(s), single-step: ...", file=sys.stderr)
        assert sys.stderr is not term
    assert sys.stderr is term
    assert "[hernandez] 1 sensor(s), single-step: ...\n" in term.getvalue()
