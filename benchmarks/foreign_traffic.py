"""Hostile traffic on the graph's DDS domain, category by category, and a flood from another
process: did the graph survive, was its result unchanged, did lockstep time out, was every
foreign message counted?

For each category of tests/tools/adversary.py (malformed fields, plausible forgeries,
replays of the graph's own messages, raw garbage, random messages), a lockstep run of a short
scenario with a foreign node streaming that category at ``--stream-rate`` messages per second
from epoch 2 until the run's evaluator is complete, compared with a clean run of the same seed.
Then a flood: another process publishes random messages at ``--flood-rate`` per second on every
topic the graph reads, for ``--flood-seconds`` or until the run is complete, during a run of the
Hernandez 3-sensor three-step scenario that starts once the flood has. ``--processes``: the
nodes in their own processes (the
foreign node and the evaluator in this one). Columns: messages sent, survived (complete, no
exception in any callback), result unchanged (bit for bit), timeouts (commands the sim waited
out, epochs the tracker closed incomplete), counted (foreign or DDS-lost, per reader),
uncounted (foreign messages a reader did not count, plus messages in no outcome counter of a
reader: must be 0). The load average is printed at the start and the end.

    .venv/bin/python benchmarks/foreign_traffic.py [--processes] [--stream-rate 50]
        [--flood-rate 2000] [--flood-seconds 10]
    .venv/bin/python benchmarks/foreign_traffic.py --quick   # one category per type, no flood
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from collections import Counter
from pathlib import Path

import numpy as np

from activetrack.scenarios import load_scenario
from activetrack_bringup.runner import RunIncomplete, run_graph
from activetrack_ros.node_base import unaccounted

# The test tooling (tests/tools: foreign traffic, message examples) is not shipped with the
# package; the benchmark imports it from the checkout and runs the flooder as a script.
TOOLS = Path(__file__).resolve().parents[1] / "tests" / "tools"
ADVERSARY = TOOLS / "adversary.py"
sys.path.insert(0, str(TOOLS))
from adversary import (  # noqa: E402
    CATEGORIES,
    READERS,
    TOPIC_OF,
    FloodProcess,
    ForeignNode,
    uncounted,
)

SHORT = "tests/ros/data/short_two_sensors.yaml"
# The flood's run: three-step planning with 3 sensors, 10-15 s in one process here, so that a
# 10-s flood covers 10 s of epochs (the two-step one took 1.4 s on a fast host).
LONG = "scenarios/hernandez_3sensor_three.yaml"


def same(a, b) -> bool:
    """Bit for bit: truth, platform paths, the sensors that looked, the track (state and
    covariance at every epoch) and the plan reports' predicted costs."""
    ra, rb = a.summary.records[0], b.summary.records[0]
    floats = [(ra.truth, rb.truth), (ra.platform_paths, rb.platform_paths)]
    floats += zip(ra.track_series(), rb.track_series(), strict=True)
    arrays = all(np.array_equal(x, y, equal_nan=True) for x, y in floats)
    costs = [[d.report and d.report.predicted_costs for d in r.decisions] for r in (ra, rb)]
    return arrays and np.array_equal(ra.looked, rb.looked) and costs[0] == costs[1]


def errors(run) -> int:
    return sum(v for c in run.diagnostics.values() for k, v in c.items() if k.startswith("errors."))


def timeouts(run) -> int:
    """Commands the sim waited out and epochs the tracker closed incomplete."""
    d = run.diagnostics
    return d.get("sim", {}).get("command_timeouts", 0) + d.get("tracker", {}).get(
        "incomplete_epochs", 0
    )


def in_no_counter(run) -> int:
    """Messages some reader received that none of its outcome counters holds."""
    return sum(abs(unaccounted(c)) for c in run.diagnostics.values())


def misses(run, sent: Counter, signed: Counter) -> list[str]:
    """Where uncounted messages are: reader and type short of foreign, reader out of balance."""
    out = []
    for name, readers in READERS.items():
        for node in readers:
            c = run.diagnostics.get(node, {})
            seen = c.get(f"foreign.{name}", 0) + c.get(f"dropped.{name}", 0)
            if seen < sent[name] - signed[name]:
                out.append(f"{node} counted {seen} of {sent[name] - signed[name]} {name}")
    out += [f"{n}: {unaccounted(c)} in no counter" for n, c in run.diagnostics.items()]
    return [m for m in out if not m.endswith(": 0 in no counter")]


def outcome(run, survived: bool, clean, sent: Counter, signed: Counter) -> dict:
    foreign = sum((sent[t] - signed[t]) * len(r) for t, r in READERS.items())
    missing = uncounted(run.diagnostics, sent, signed) + in_no_counter(run)
    return dict(
        sent=sum(sent.values()),
        survived=survived,
        unchanged=survived and same(run, clean),
        timeouts=timeouts(run),
        counted=foreign - uncounted(run.diagnostics, sent, signed),
        uncounted=missing,
        misses=misses(run, sent, signed),
    )


def category_row(name: str, clean, tmp: Path, opts: dict, **foreign_kwargs) -> dict:
    nodes = []
    dt = load_scenario(SHORT).dt

    def add(graph):
        evaluator = graph.evaluator
        stop = lambda: evaluator.complete  # noqa: E731
        foreign = ForeignNode(dt=dt, context=graph.context, stop=stop, **foreign_kwargs)
        nodes.append(graph.add(foreign))

    # Between processes the sim holds its first epoch until the foreign node has joined:
    # a stream sent before discovery completes reaches nobody (and is no probe).
    wait = {"wait_for": "1"} if opts["processes"] else {}
    try:
        run = run_graph(SHORT, run_dir=tmp / name, before_spin=add, **wait, **opts)
        survived = errors(run) == 0
    except RunIncomplete as exc:
        run, survived = exc.result, False
    f = nodes[0]
    return dict(name=name, **outcome(run, survived, clean, f.sent, f.sent_signed))


def flood_row(rate: float, seconds: float, tmp: Path, opts: dict) -> dict:
    os.environ.setdefault("ROS_DOMAIN_ID", str(150 + os.getpid() % 50))
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    clean = run_graph(LONG, run_dir=tmp / "flood_clean", **opts)
    flood = FloodProcess(rate, seconds, os.environ)
    try:
        run = run_graph(
            LONG,
            run_dir=tmp / "flood",
            # the run starts once the flood has (in one process: before the sim's first epoch)
            before_spin=flood.start_under,
            during_spin=flood.stop_when_complete,
            **opts,
        )
        survived = errors(run) == 0
    except RunIncomplete as exc:
        run, survived = exc.result, False
    finally:
        sent = flood.finish()
    row = outcome(run, survived, clean, sent, Counter())
    name = f"flood {rate:g}/s, at most {seconds:g} s (other process)"
    return dict(name=name, **row, wall=(clean.wall_time_s, run.wall_time_s))


def load() -> str:
    return " ".join(f"{x:.1f}" for x in os.getloadavg())


def _category_rows(categories, clean, tmp: Path, opts: dict, rate: float) -> list[dict]:
    rows = [
        category_row(cat.name, clean, tmp, opts, categories=[cat.name], rate=rate)
        for cat in categories
    ]
    rows.append(category_row("replay_of_genuine", clean, tmp, opts, replay=True, rate=rate))
    rows.append(category_row("raw_garbage", clean, tmp, opts, garbage=50, rate=rate))
    floods = {t: 30 for t in TOPIC_OF}
    rows.append(category_row("random_messages", clean, tmp, opts, floods=floods, seed=1, rate=rate))
    return rows


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--processes", action="store_true", help="one process per node")
    parser.add_argument("--stream-rate", type=float, default=50.0, help="messages per second")
    parser.add_argument("--flood-rate", type=float, default=2000.0)
    parser.add_argument("--flood-seconds", type=float, default=10.0)
    parser.add_argument("--no-flood", action="store_true")
    parser.add_argument("--flood-only", action="store_true", help="the flood row alone")
    parser.add_argument(
        "--quick", action="store_true", help="one category per message type, no flood"
    )
    args = parser.parse_args()
    categories = CATEGORIES
    if args.quick:  # the first category of each message type
        firsts = {c.msg_type: c for c in reversed(CATEGORIES)}
        categories = [c for c in CATEGORIES if firsts[c.msg_type] is c]
    opts = dict(record=False, plots=False, processes=args.processes)
    mode = "processes" if args.processes else "in-process"
    print(f"mode={mode} lockstep stream={args.stream_rate:g}/s load at start: {load()}")
    rate = args.stream_rate
    rows = []
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        clean = run_graph(SHORT, run_dir=tmp / "clean", **opts)
        if not args.flood_only:
            rows += _category_rows(categories, clean, tmp, opts, rate)
        if not (args.no_flood or args.quick):
            rows.append(flood_row(args.flood_rate, args.flood_seconds, tmp, opts))
    width = max(len(r["name"]) for r in rows)
    print(
        f"{'category':<{width}}  {'sent':>6}  survived  unchanged  timeouts  {'counted':>8}  "
        "uncounted"
    )
    for r in rows:
        print(
            f"{r['name']:<{width}}  {r['sent']:>6}  {'yes' if r['survived'] else 'NO':>8}  "
            f"{'yes' if r['unchanged'] else 'NO':>9}  {r['timeouts']:>8}  {r['counted']:>8}  "
            f"{r['uncounted']:>9}"
        )
    for r in rows:
        for m in r["misses"]:
            print(f"  {r['name']}: {m}")
    for r in rows:
        if "wall" in r:
            print(f"flood run wall time {r['wall'][1]:.1f} s (clean {r['wall'][0]:.1f} s)")
    print(f"load at end: {load()}")
    n = len(rows)
    print(
        f"mode={mode} categories={n} survived={sum(r['survived'] for r in rows)} "
        f"unchanged={sum(r['unchanged'] for r in rows)}/{n} "
        f"uncounted={sum(r['uncounted'] for r in rows)} "
        f"timeouts={sum(r['timeouts'] for r in rows)}"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
