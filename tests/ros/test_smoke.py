"""The `make run` smoke: three nodes up, one message of every type exchanged."""

import pytest

from activetrack_bringup.cli import main
from activetrack_bringup.examples import MESSAGE_TYPES
from activetrack_bringup.smoke import run_smoke


@pytest.mark.ros
def test_smoke_passes_every_type_through_the_graph():
    result = run_smoke(timeout=10.0)
    assert [name for name, *_ in result.rows] == [t.__name__ for t in MESSAGE_TYPES]
    assert result.ok, result.rows


@pytest.mark.ros
def test_smoke_command_line_exit_code(capsys):
    assert main(["smoke"]) == 0
    assert "smoke: OK" in capsys.readouterr().out
