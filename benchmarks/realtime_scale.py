"""Real-time factor of `activetrack run` on the 30-target scene, in one process (issue 28).

The scene is ``planning_scale.scale_scene_data(30, 4)`` (multi-target (b) scaled: 30 targets,
4 platforms with beam radars, dt 1 s) with ``--steps`` epochs, written as a scenario file to a
temporary folder. Each repetition runs `activetrack run` on it twice, each time as a fresh
process as a user runs it (what a process does once, e.g. the planner's IRF tables, counts),
lockstep, the graph in one process, the order alternating: as the command runs by default
(the bag recorded) and with ``--no-bag``. Both pass ``--no-plots``: the command draws the plots
after its clock stops, so they are not in the real-time factor (sim seconds / wall seconds of
the run, from its ``summary.json``). One untimed warm-up run comes first: numba's disk cache
read once, and a scene's first run on a machine computes its IRF tables, which later runs
read from disk (``models/irf.py``; about 0.35 s of the first run). The runs take a DDS
domain of their own (``ROS_DOMAIN_ID``, unless set): in one process a run joins domain 0,
where graphs of other jobs on a shared host would match its topics and cost it their
traffic. Every run must give the same mean GOSPA to the last bit.
Prints the machine line (``machine.describe``), each run's factor and the load average, and
last ``run_30t_real_time_factor=<median>`` (the default command's median).

    .venv/bin/python benchmarks/realtime_scale.py [--repeats 5] [--steps 60] [--targets 30]
        [--platforms 4]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent))

from machine import describe
from planning_scale import scale_scene_data

ACTIVETRACK = Path(sys.executable).with_name("activetrack")  # the venv's command
MODES = {"default": [], "no-bag": ["--no-bag"]}
ENV = {
    **os.environ,
    "ROS_DOMAIN_ID": os.environ.get("ROS_DOMAIN_ID") or str(150 + os.getpid() % 80),
}


def write_scene(folder: Path, n_targets: int, n_platforms: int, steps: int) -> Path:
    """The scene as a scenario file (plain floats, as a user would write it)."""
    data = json.loads(json.dumps(scale_scene_data(n_targets, n_platforms), default=float))
    data.update(steps=steps, name=f"scale_{n_targets}t_{n_platforms}p")
    path = folder / f"{data['name']}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def one_run(scenario: Path, folder: Path, tag: str, mode: str) -> tuple[float, float, float]:
    """(real-time factor, wall s, mean GOSPA) of one `activetrack run` in a fresh run folder."""
    out = folder / tag
    cmd = [str(ACTIVETRACK), "run", str(scenario), "--no-plots", "--out", str(out), *MODES[mode]]
    proc = subprocess.run(cmd, capture_output=True, text=True, check=False, env=ENV)
    if proc.returncode != 0:
        raise RuntimeError(f"run {tag}: exit {proc.returncode}: {proc.stderr[-2000:]}")
    summary = json.loads((out / "summary.json").read_text())
    return summary["real_time_factor"], summary["wall_time_s"], summary["mean_gospa"]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--steps", type=int, default=60)
    ap.add_argument("--targets", type=int, default=30)
    ap.add_argument("--platforms", type=int, default=4)
    args = ap.parse_args(argv)
    print(describe())
    factors: dict[str, list[float]] = {mode: [] for mode in MODES}
    with tempfile.TemporaryDirectory(prefix="realtime_scale_") as tmp:
        folder = Path(tmp)
        scenario = write_scene(folder, args.targets, args.platforms, args.steps)
        print(
            f"# {scenario.name}: {args.steps} epochs of 1 s, one process, lockstep, "
            f"ROS_DOMAIN_ID={ENV['ROS_DOMAIN_ID']}"
        )
        _, _, gospa = one_run(scenario, folder, "warmup", "no-bag")
        for i in range(args.repeats):
            order = list(MODES) if i % 2 == 0 else list(MODES)[::-1]
            for mode in order:
                rtf, wall, g = one_run(scenario, folder, f"{mode}_{i}", mode)
                if g != gospa:
                    raise RuntimeError(f"run {i} {mode}: mean GOSPA {g!r}, first run {gospa!r}")
                factors[mode].append(rtf)
                print(
                    f"run {i} {mode:>8}: {rtf:5.1f}x real time, wall {wall:5.2f} s, "
                    f"load average {os.getloadavg()[0]:.1f}",
                    flush=True,
                )
    for mode, values in factors.items():
        print(
            f"{mode:>8}: median {statistics.median(values):.1f}x "
            f"[{min(values):.1f}, {max(values):.1f}] over {len(values)} runs"
        )
    print(f"mean GOSPA {gospa!r} m in every run; {describe()}")
    print(f"run_{args.targets}t_real_time_factor={statistics.median(factors['default']):.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
