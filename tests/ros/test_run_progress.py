"""`activetrack run` on a terminal: the evaluator's tracked epochs drive the bar (through the
runner's ``during_spin`` hook); the run's numbers are those of the batch loop all the same."""

import io

import pytest
from parity import assert_same_run

from activetrack.closed_loop.batch import run_batch
from activetrack.scenarios import load_scenario
from activetrack_bringup.progress import Bar, epoch_hook
from activetrack_bringup.runner import run_graph

SCENARIO = "tests/ros/data/short_two_sensors.yaml"
pytestmark = pytest.mark.ros


class FakeTerminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_epoch_bar_follows_the_run(tmp_path):
    term = FakeTerminal()
    with Bar("run", unit="epoch", file=term) as bar:
        result = run_graph(
            SCENARIO, run_dir=tmp_path, record=False, plots=False, during_spin=epoch_hook(bar)
        )
        assert bar.done == load_scenario(SCENARIO).steps
    assert "run:" in term.getvalue() and "epoch" in term.getvalue()
    batch = run_batch(load_scenario(SCENARIO), runs=1)
    assert_same_run(result.summary.records[0], batch.records[0])
