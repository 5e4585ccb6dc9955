"""Hostile traffic on the graph's DDS domain, category by category, and a flood from another
process: did the graph survive, was its result unchanged, was every foreign message counted?

For each category of tests/tools/adversary.py (malformed fields, plausible forgeries,
replays of the graph's own messages, raw garbage, random messages), a lockstep run of a short
scenario in one process with a foreign node publishing that category at epoch 2, compared
with a clean run of the same seed. Then a flood: another process publishes random messages at
``--flood-rate`` per second for ``--flood-seconds`` on four of the graph's topics during a run
of the Hernandez 3-sensor two-step scenario. Columns: messages sent, survived (complete, no
exception in any callback), result unchanged (bit for bit), counted (foreign or DDS-lost, per
reader), uncounted (must be 0).

    .venv/bin/python benchmarks/foreign_traffic.py [--flood-rate 2000] [--flood-seconds 10]
    .venv/bin/python benchmarks/foreign_traffic.py --quick   # one category per type, no flood
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from collections import Counter
from pathlib import Path

import numpy as np

from activetrack.scenarios import load_scenario
from activetrack_bringup.runner import RunIncomplete, run_graph
from msgs_defs.msg import ManoeuvreCommand, PlatformState, Scan, TrackArray

# The test tooling (tests/tools: foreign traffic, message examples) is not shipped with the
# package; the benchmark imports it from the checkout and runs the flooder as a script.
TOOLS = Path(__file__).resolve().parents[1] / "tests" / "tools"
ADVERSARY = TOOLS / "adversary.py"
sys.path.insert(0, str(TOOLS))
from adversary import CATEGORIES, READERS, TOPIC_OF, ForeignNode, uncounted  # noqa: E402

SHORT = "tests/ros/data/short_two_sensors.yaml"
LONG = "scenarios/hernandez_3sensor_two.yaml"


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


def category_row(name: str, clean, tmp: Path, **foreign_kwargs) -> dict:
    nodes = []
    dt = load_scenario(SHORT).dt

    def add(graph):
        nodes.append(graph.add(ForeignNode(dt=dt, context=graph.context, **foreign_kwargs)))

    try:
        run = run_graph(SHORT, run_dir=tmp / name, record=False, plots=False, before_spin=add)
        survived = errors(run) == 0
    except RunIncomplete as exc:
        run, survived = exc.result, False
    f = nodes[0]
    foreign = sum((f.sent - f.sent_signed)[t] * len(r) for t, r in READERS.items())
    missing = uncounted(run.diagnostics, f.sent, f.sent_signed)
    return dict(
        name=name,
        sent=sum(f.sent.values()),
        survived=survived,
        unchanged=survived and same(run, clean),
        counted=foreign - missing,
        uncounted=missing,
    )


def flood_row(rate: float, seconds: float, tmp: Path) -> dict:
    env = {k: v for k, v in os.environ.items() if k != "_ROS_WHEELS_BOOTSTRAP_COMPLETE"}
    env.setdefault("ROS_DOMAIN_ID", str(150 + os.getpid() % 50))
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    os.environ.update({k: env[k] for k in ("ROS_DOMAIN_ID", "ROS_AUTOMATIC_DISCOVERY_RANGE")})
    flooded = (Scan, PlatformState, TrackArray, ManoeuvreCommand)
    readers = [f"{TOPIC_OF[t]}={len(READERS[t.__name__])}" for t in flooded]
    clean = run_graph(LONG, run_dir=tmp / "flood_clean", record=False, plots=False)
    cmd = [sys.executable, str(ADVERSARY), "--rate", str(rate)]
    proc = subprocess.Popen(
        [*cmd, "--duration", str(seconds), *readers], env=env, stdout=subprocess.PIPE, text=True
    )
    try:
        run = run_graph(LONG, run_dir=tmp / "flood", record=False, plots=False)
        sent = Counter(json.loads(proc.communicate(timeout=600)[0].strip().splitlines()[-1]))
    finally:
        proc.kill()
    total = sum(sent[t] * len(r) for t, r in READERS.items())
    missing = uncounted(run.diagnostics, sent, Counter())
    return dict(
        name=f"flood {rate:g}/s x {seconds:g} s (other process)",
        sent=sum(sent.values()),
        survived=errors(run) == 0,
        unchanged=same(run, clean),
        counted=total - missing,
        uncounted=missing,
        wall=(clean.wall_time_s, run.wall_time_s),
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--flood-rate", type=float, default=2000.0)
    parser.add_argument("--flood-seconds", type=float, default=10.0)
    parser.add_argument("--no-flood", action="store_true")
    parser.add_argument(
        "--quick", action="store_true", help="one category per message type, no flood"
    )
    args = parser.parse_args()
    categories = CATEGORIES
    if args.quick:  # the first category of each message type
        firsts = {c.msg_type: c for c in reversed(CATEGORIES)}
        categories = [c for c in CATEGORIES if firsts[c.msg_type] is c]
    rows = []
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        clean = run_graph(SHORT, run_dir=tmp / "clean", record=False, plots=False)
        for cat in categories:
            rows.append(category_row(cat.name, clean, tmp, categories=[cat.name]))
        rows.append(category_row("replay_of_genuine", clean, tmp, replay=True))
        rows.append(category_row("raw_garbage", clean, tmp, garbage=50))
        floods = {t: 300 for t in TOPIC_OF}
        rows.append(category_row("random_messages", clean, tmp, floods=floods, seed=1))
        if not (args.no_flood or args.quick):
            rows.append(flood_row(args.flood_rate, args.flood_seconds, tmp))
    width = max(len(r["name"]) for r in rows)
    print(f"{'category':<{width}}  {'sent':>6}  survived  unchanged  {'counted':>8}  uncounted")
    for r in rows:
        print(
            f"{r['name']:<{width}}  {r['sent']:>6}  {'yes' if r['survived'] else 'NO':>8}  "
            f"{'yes' if r['unchanged'] else 'NO':>9}  {r['counted']:>8}  {r['uncounted']:>9}"
        )
    flood = [r for r in rows if "wall" in r]
    for r in flood:
        print(f"flood run wall time {r['wall'][1]:.1f} s (clean {r['wall'][0]:.1f} s)")
    n = len(rows)
    print(
        f"categories={n} survived={sum(r['survived'] for r in rows)} "
        f"unchanged={sum(r['unchanged'] for r in rows)} "
        f"uncounted={sum(r['uncounted'] for r in rows)}"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
