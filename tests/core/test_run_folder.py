"""run_dir_for: the run folder is always inside runs/, whatever the scenario is called."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from activetrack_bringup.run_folder import run_dir_for, safe_name

STAMP = r"-\d{8}-\d{6}-\d{6}"  # YYYYmmdd-HHMMSS-microseconds
HOSTILE = [
    "../../x",
    "../../../../etc/cron.d/evil",
    "/etc/passwd",
    "/",
    "",
    ".",
    "..",
    ".hidden",
    "...",
    "a/../../b",
    "a\\..\\..\\b",
    "C:\\Windows\\x",
    "~/x",
    "name with spaces",
    "ünïcödé/名前",
    "\x00nul",
    "line\nbreak",
    "-",
    "x" * 1000,
]


@pytest.mark.parametrize("name", HOSTILE, ids=range(len(HOSTILE)))
def test_the_folder_is_inside_root_with_a_safe_name(name, tmp_path):
    root = tmp_path / "runs"
    folder = run_dir_for(name, root=root)
    assert folder.parent == root
    assert root.resolve() in folder.resolve().parents
    assert re.fullmatch(r"[A-Za-z0-9_-][A-Za-z0-9_.-]*" + STAMP, folder.name)
    assert len(folder.name) <= 100 + 23
    folder.mkdir(parents=True)  # it is a real, creatable folder name
    assert folder.is_dir() and folder.parent == root


def test_safe_name_keeps_what_is_safe_and_never_is_empty():
    assert safe_name("hernandez_2sensor_two") == "hernandez_2sensor_two"
    assert safe_name("ramdaras_case3_pd-mre.v2") == "ramdaras_case3_pd-mre.v2"
    assert safe_name("../../x") == "_.._x"
    assert safe_name("/etc/passwd") == "_etc_passwd"
    assert safe_name("") == safe_name("..") == safe_name(".") == "scenario"
    assert safe_name("ünï") == "_n_"
    assert not safe_name(".bashrc").startswith(".")


def test_default_root_is_runs_and_timestamps_have_microseconds():
    folder = run_dir_for("default")
    assert folder.parent == Path("runs")
    assert re.fullmatch("default" + STAMP, folder.name)


def test_an_explicit_out_is_the_users_choice(tmp_path):
    assert run_dir_for("../../x", out=tmp_path / "mine") == tmp_path / "mine"
    assert run_dir_for("x", out="rel/dir") == Path("rel/dir")
    assert run_dir_for("x", out="").parent == Path("runs")  # empty: the default
