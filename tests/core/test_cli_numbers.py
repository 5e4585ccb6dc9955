"""Numbers on the command lines: argparse rejects bad ones with one ``error:`` line, exit 2.

``activetrack`` itself (activetrack_bringup.cli, cli_types) and the experiments' own parsers
behind ``activetrack reproduce NAME`` (activetrack.argtypes). Nothing here needs ROS: the
parser fails before any command runs.
"""

from __future__ import annotations

import argparse

import pytest

from activetrack.argtypes import float_in_range, int_in_range
from activetrack_bringup import cli_types
from activetrack_bringup.cli import build_parser
from activetrack_bringup.cli import main as cli_main
from activetrack_experiments import hernandez

S = "scenarios/default.yaml"
# (argv, the option named in the error, text of the allowed range that must appear)
BAD = [
    (["batch", S, "--runs", "0"], "--runs", "must be an integer in [1, 100000], got '0'"),
    (["batch", S, "--runs", "-1"], "--runs", "[1, 100000], got '-1'"),
    (["batch", S, "--runs", "abc"], "--runs", "[1, 100000], got 'abc'"),
    (["batch", S, "--runs", "2.5"], "--runs", "[1, 100000], got '2.5'"),
    (["batch", S, "--runs", "1e3"], "--runs", "[1, 100000], got '1e3'"),
    (["batch", S, "--runs", "100001"], "--runs", "[1, 100000], got '100001'"),
    (["batch", S, "--runs", "9" * 5000], "--runs", "must be an integer in [1, 100000]"),
    (["run", S, "--timeout", "0"], "--timeout", "must be a finite number in (0, 1e+07]"),
    (["run", S, "--timeout", "nan"], "--timeout", "(0, 1e+07], got 'nan'"),
    (["run", S, "--timeout", "inf"], "--timeout", "(0, 1e+07], got 'inf'"),
    (["run", S, "--timeout", "-5"], "--timeout", "(0, 1e+07], got '-5'"),
    (["run", S, "--timeout", "1e300"], "--timeout", "(0, 1e+07], got '1e300'"),
    (["run", S, "--run", "-1"], "--run", "must be an integer in [0, 9223372036854775807]"),
    (["run", S, "--run", "x"], "--run", "got 'x'"),
    (["record", "bag", "--duration", "-1"], "--duration", "(0, 1e+07], got '-1'"),
    (["record", "bag", "--duration", "0"], "--duration", "(0, 1e+07], got '0'"),
    (["record", "bag", "--duration", "nan"], "--duration", "got 'nan'"),
    (
        ["play", "bag", "--rate", "0"],
        "--rate",
        "must be a finite number in [0.001, 1e+06], got '0'",
    ),
    (["play", "bag", "--rate", "-1"], "--rate", "[0.001, 1e+06], got '-1'"),
    (["play", "bag", "--rate", "nan"], "--rate", "got 'nan'"),
    (["play", "bag", "--rate", "inf"], "--rate", "got 'inf'"),
    (["play", "bag", "--rate", "1e-9"], "--rate", "[0.001, 1e+06], got '1e-9'"),  # for ever
    (["bag", "retrack", "b", "--scenario", S, "--run", "-2"], "--run", "got '-2'"),
    # the experiments' own parsers (activetrack reproduce NAME ARGS...)
    (["reproduce", "hernandez", "--runs", "-1"], "--runs", "[0, 100000] (0: the bounds only)"),
    (["reproduce", "hernandez", "--particles", "0"], "--particles", "[1, 1000000], got '0'"),
    (["reproduce", "hernandez", "--particles", "1e4"], "--particles", "got '1e4'"),
    (["reproduce", "hernandez", "--jobs", "0"], "--jobs", "[1, 256], got '0'"),
    (["reproduce", "hernandez", "--mc-samples", "1000000"], "--mc-samples", "[1, 100000]"),
    (["reproduce", "hernandez", "--grid-size", "1"], "--grid-size", "[2, 1001], got '1'"),
    (["reproduce", "hernandez", "--seed", "-1"], "--seed", "got '-1'"),
    (
        ["reproduce", "hernandez", "--mc-samples", "100000"],
        "--mc-samples",
        "--grid-size 101 scores 2.05e+08 sample-candidate pairs at once",
    ),
    (
        ["reproduce", "hernandez", "--search", "grid"],
        "--search grid",
        "with --horizons 2 costs 1.04e+08 cost evaluations per decision, at most 1e+07",
    ),
    (["reproduce", "ramdaras", "--runs", "0"], "--runs", "[1, 100000], got '0'"),
    (["reproduce", "ramdaras", "--jobs", "-3"], "--jobs", "[1, 256], got '-3'"),
    (
        ["reproduce", "valverde", "--runs", "1"],
        "--runs",
        "[2, 100000] (the Monte Carlo error needs two runs), got '1'",
    ),
    (["reproduce", "valverde", "--runs", "0"], "--runs", "got '0'"),
    (["reproduce", "valverde", "--steps", "0"], "--steps", "[1, 1000000], got '0'"),
    (["reproduce", "valverde", "--seed", "-1"], "--seed", "got '-1'"),
    (["reproduce", "valverde", "--jobs", "0"], "--jobs", "[1, 256], got '0'"),
    (
        ["reproduce", "valverde", "--runs", "100000", "--steps", "1000"],
        "--runs x --steps",
        "must be <= 2.5e+07 (the runs are held in memory together), got 100000 x 1000",
    ),
    (["reproduce", "vanderhook", "--runs", "0"], "--runs", "[1, 100000], got '0'"),
    (["reproduce", "vanderhook", "--seed", "-3"], "--seed", "got '-3'"),
    (["reproduce", "vanderhook", "--jobs", "-1"], "--jobs", "[1, 256], got '-1'"),
]


@pytest.mark.parametrize(
    ("argv", "option", "expected"), BAD, ids=[" ".join(b[0])[:60] for b in BAD]
)
def test_bad_number_is_a_one_line_usage_error(argv, option, expected, capsys):
    with pytest.raises(SystemExit) as info:
        cli_main(argv)
    assert info.value.code == 2
    out, err = capsys.readouterr()
    assert out == ""  # nothing ran
    assert "Traceback" not in err
    errors = [line for line in err.splitlines() if "error:" in line]
    assert len(errors) == 1, err
    assert errors[0] == err.strip().splitlines()[-1]  # usage first, the one error line last
    assert option in errors[0]
    assert expected in errors[0], errors[0]


@pytest.mark.parametrize(
    ("argv", "dest", "value"),
    [
        (["batch", S, "--runs", "3"], "runs", 3),
        (["batch", S, "--runs", "100000"], "runs", 100000),
        (["run", S, "--timeout", "0.5"], "timeout", 0.5),
        (["run", S, "--run", "0"], "run", 0),
        (["record", "b", "--duration", "2.5"], "duration", 2.5),
        (["play", "b", "--rate", "1e-3"], "rate", 1e-3),
        (["bag", "retrack", "b", "--scenario", S, "--run", "7"], "run", 7),
    ],
)
def test_good_numbers_are_accepted(argv, dest, value):
    assert getattr(build_parser().parse_args(argv), dest) == value


def test_defaults_are_unchanged():
    assert build_parser().parse_args(["batch", S]).runs == 1
    run = build_parser().parse_args(["run", S])
    assert (run.timeout, run.run) == (600.0, None)
    assert build_parser().parse_args(["play", "b"]).rate == 1.0


def test_hernandez_keeps_runs_zero_for_the_bounds_only():
    # --runs 0 is Hernandez's documented "planning bounds only, no PF runs" mode.
    args = hernandez._parse(["--runs", "0", "--no-comparison"])
    assert args.runs == 0
    assert (args.sensor_counts, args.horizon_list) == ([1, 2, 3], [1, 2])


def test_hernandez_options_are_checked_without_argparse():
    # The same checks back reproduce(...) (ValueError) and the command line (usage error).
    assert hernandez.check_options(sensors=["3", "1"], horizons=[2]) == ([1, 3], [2])
    with pytest.raises(ValueError, match="--sensors must be among 1,2,3"):
        hernandez.check_options(sensors=[4])
    with pytest.raises(ValueError, match="comma-separated integers"):
        hernandez.check_options(horizons=["x"])
    with pytest.raises(ValueError, match="scores 2.05e\\+08 sample-candidate pairs"):
        hernandez.check_options(mc_samples=100000)
    assert hernandez.check_options(mc_samples=100000, comparison=False)[0] == [1, 2, 3]


def test_type_functions_check_both_ends_and_say_what_is_allowed():
    half_open = float_in_range(0.0, 1.0, lo_inclusive=False)
    assert half_open("1") == 1.0
    for text in ("0", "1.0000001", "nan", "-inf", "", "one"):
        with pytest.raises(argparse.ArgumentTypeError, match=r"finite number in \(0, 1\]"):
            half_open(text)
    count = int_in_range(2, 5, note="why")
    assert count(" 3 ") == 3
    for text in ("1", "6", "3.0", "0x3"):
        with pytest.raises(argparse.ArgumentTypeError, match=r"integer in \[2, 5\] \(why\)"):
            count(text)
    assert cli_types.runs("1") == 1
    with pytest.raises(argparse.ArgumentTypeError):
        cli_types.rate("1e7")
