"""Ctrl-C and SIGTERM stop `activetrack run` at any moment: 20 moments spread from start-up to
cleanup (SIGINT, exit 130) and a few more with SIGTERM (exit 143, one process and
``--processes``), each within 2 s, with a summary.json that says the run is incomplete.

Moment 0 is when the command line has its handlers (SIGTERM is caught: /proc/PID/status);
before that only Python itself runs. The moments are spread over the phases of a run of the
same scenario here, now (measured first), so that they cover start-up, the epochs, the stop
and the figures whatever the load; two runs at a time keep the test short.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

SCENARIO = "tests/ros/data/short_two_sensors.yaml"  # 8 epochs
# Its epochs, for the sweep: 40 (about 3 s on a fast host; 8 took 0.6 s there, and runs that
# went faster than the measured ones ended before their moments: 15 of 20 real, once).
STEPS = 40
EXE = str(Path(sys.executable).parent / "activetrack")
STOP_S = 2.0  # the promise: stopped within 2 s of the signal
EXIT_INSTANT_S = 0.05  # a process that had ended: gone this soon after the signal, rc 0
SIGINT_MOMENTS = 20
pytestmark = [pytest.mark.ros, pytest.mark.slow, pytest.mark.usefixtures("localhost_discovery")]


@pytest.fixture(scope="module")
def scenario(tmp_path_factory) -> Path:
    """The short scenario with STEPS epochs."""
    text = Path(SCENARIO).read_text()
    assert text.count("\nsteps: 8\n") == 1
    path = tmp_path_factory.mktemp("scenario") / "long_two_sensors.yaml"
    path.write_text(text.replace("\nsteps: 8\n", f"\nsteps: {STEPS}\n"))
    return path


def _launch(scenario: Path, out: Path, *extra: str) -> subprocess.Popen:
    env = {k: v for k, v in os.environ.items() if k != "_ROS_WHEELS_BOOTSTRAP_COMPLETE"}
    return subprocess.Popen(
        [EXE, "run", str(scenario), "--out", str(out), *extra],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        # a terminal's foreground job: SIGINT not ignored (the command line takes it anyway)
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )


def _handlers_installed(proc: subprocess.Popen, timeout: float = 60.0) -> float:
    """When the process first catches SIGTERM (its command line has run its first line)."""
    deadline = time.monotonic() + timeout
    status = Path(f"/proc/{proc.pid}/status")
    while time.monotonic() < deadline:
        try:
            caught = next(
                int(line.split()[1], 16)
                for line in status.read_text().splitlines()
                if line.startswith("SigCgt:")
            )
        except (OSError, StopIteration):
            caught = 0
        if caught & (1 << (signal.SIGTERM - 1)):
            return time.monotonic()
        assert proc.poll() is None, proc.communicate()[0]
        time.sleep(0.005)
    raise AssertionError("the command line never installed its signal handlers")


class _Output(threading.Thread):
    """Reads a run's output as it comes; ``graph`` is set at the ``ROS`` line, which the
    command line prints just before it starts the graph."""

    def __init__(self, proc: subprocess.Popen):
        super().__init__(daemon=True)
        self.proc, self.lines, self.graph = proc, [], threading.Event()
        self.start()

    def run(self) -> None:
        for line in self.proc.stdout:
            self.lines.append(line)
            if line.startswith("  ROS "):
                self.graph.set()
        self.graph.set()  # ended without starting the graph: wait no longer

    @property
    def text(self) -> str:
        return "".join(self.lines)


def _complete_before(out: Path, wall: float) -> bool:
    path = out / "summary.json"
    return (
        path.exists() and path.stat().st_mtime <= wall and json.loads(path.read_text())["complete"]
    )


def _interrupt(scenario: Path, out: Path, moment: tuple[str, float], sig: int, *extra: str) -> dict:
    """One run, ``sig`` sent at ``moment``: (anchor, seconds after it), the anchor "start"
    (moment 0) or "graph" (the ROS line); what happened."""
    anchor, offset = moment
    proc = _launch(scenario, out, *extra)
    t0 = _handlers_installed(proc)
    output = _Output(proc)
    if anchor == "graph":
        output.graph.wait(120)
        t0 = time.monotonic()
    time.sleep(max(0.0, t0 + offset - time.monotonic()))
    sent_wall, sent = time.time(), time.monotonic()
    ended_before = proc.poll() is not None
    proc.send_signal(sig)
    try:
        proc.wait(timeout=60)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()
    stopped = time.monotonic() - sent
    # A process exits the instant after its last check for a signal (os._exit): one that
    # stopped within EXIT_INSTANT_S with rc 0 and a complete summary written before the
    # signal had ended its run; the signal came too late to be one of the run's moments.
    ended_before = ended_before or (
        proc.returncode == 0 and stopped < EXIT_INSTANT_S and _complete_before(out, sent_wall)
    )
    output.join(10)
    path = out / "summary.json"
    summary = json.loads(path.read_text()) if path.exists() else None
    written = path.stat().st_mtime if path.exists() else None
    return {
        "moment": f"{anchor} + {offset:.2f} s",
        "rc": proc.returncode,
        "stopped": stopped,
        "output": output.text,
        "summary": summary,
        "before_signal": written is not None and written <= sent_wall,
        "ended_before": ended_before,
    }


def _problems(r: dict, code: int) -> list[str]:
    at = f"signal at {r['moment']}"
    if r["ended_before"]:
        return []  # the run had ended: no moment of it (counted below)
    out = []
    if r["rc"] != code:
        out.append(f"{at}: exit code {r['rc']}, not {code}\n{r['output'][-1500:]}")
    if r["stopped"] > STOP_S:
        out.append(f"{at}: stopped {r['stopped']:.2f} s after it")
    if "Traceback" in r["output"]:
        out.append(f"{at}: traceback\n{r['output'][-1500:]}")
    s = r["summary"]
    if s is None:
        out.append(f"{at}: no summary.json")
    elif s["complete"] and not r["before_signal"]:  # only a run that had finished is complete
        out.append(f"{at}: summary complete, written after the signal")
    elif not s["complete"] and not (
        s["status"] == "interrupted" and s["detail"].startswith(r["sig_name"])
    ):
        out.append(f"{at}: summary status {s['status']!r} ({s['detail']!r})")
    return out


def _sweep(scenario: Path, tmp_path: Path, moments: list, sig: int, *extra: str) -> list[dict]:
    with ThreadPoolExecutor(max_workers=2) as pool:  # two runs at a time
        runs = list(
            pool.map(
                lambda im: _interrupt(scenario, tmp_path / f"run{im[0]}", im[1], sig, *extra),
                enumerate(moments),
            )
        )
    for r in runs:
        r["sig_name"] = signal.Signals(sig).name
    return runs


def _phases(scenario: Path, tmp_path: Path) -> tuple[float, float, float]:
    """Two uninterrupted runs at once, here and now (the sweep's conditions): seconds from
    moment 0 to the graph's start (the ROS line), the epochs' wall time, and from the graph's
    start to the exit; the longer of the two each."""

    def one(out: Path) -> tuple[float, float, float]:
        proc = _launch(scenario, out)
        t0 = _handlers_installed(proc)
        output = _Output(proc)
        output.graph.wait(120)
        graph_at = time.monotonic()
        proc.wait(timeout=120)
        output.join(10)
        assert proc.returncode == 0, output.text
        wall = json.loads((out / "summary.json").read_text())["wall_time_s"]
        return graph_at - t0, wall, time.monotonic() - graph_at

    with ThreadPoolExecutor(max_workers=2) as pool:
        both = list(pool.map(one, [tmp_path / "calibration0", tmp_path / "calibration1"]))
    return tuple(max(values) for values in zip(*both, strict=True))


def _spread(anchor: str, start: float, stop: float, n: int) -> list[tuple[str, float]]:
    return [(anchor, start + (stop - start) * (i + 0.5) / n) for i in range(n)]


def test_ctrl_c_at_twenty_moments_and_sigterm_at_four(scenario, tmp_path):
    startup, wall, after = _phases(scenario, tmp_path)
    # 8 moments in the start-up (imports, the scenario, the nodes), 8 in the epochs
    # (deserialisation, kernels, bag writes), 4 in the stop, summary and figures.
    # (Only the last four draw the figures: they take seconds that the others need not wait.)
    # (A run here may go faster than the measured ones: the spans stop short of their ends.)
    moments = _spread("start", 0.0, startup, 8) + _spread("graph", 0.0, 0.6 * wall, 8)
    runs = _sweep(scenario, tmp_path / "int", moments, signal.SIGINT, "--no-plots")
    end = _spread("graph", 0.6 * wall, 0.6 * after, 4)
    runs += _sweep(scenario, tmp_path / "end", end, signal.SIGINT)
    assert len(runs) == SIGINT_MOMENTS
    term = _sweep(
        scenario,
        tmp_path / "term",
        [("start", startup / 2), ("graph", wall / 2)],
        signal.SIGTERM,
        "--no-plots",
    )
    # node processes: in the start-up, and once they run (their discovery takes seconds)
    term += _sweep(
        scenario,
        tmp_path / "proc",
        [("start", startup / 2), ("graph", 3.0)],
        signal.SIGTERM,
        "--processes",
        "--no-plots",
    )
    problems = [p for r in runs for p in _problems(r, 130)]
    problems += [p for r in term for p in _problems(r, 143)]
    table = "\n".join(
        f"{r['sig_name']:7} at {r['moment']:>14}: rc {r['rc']}, stopped in "
        f"{r['stopped']:.2f} s, epochs {(r['summary'] or {}).get('epochs_completed')}"
        + (" (the run had ended)" if r["ended_before"] else "")
        for r in runs + term
    )
    print(f"\nstart-up {startup:.2f} s, epochs {wall:.2f} s, graph to exit {after:.2f} s\n{table}")
    assert not problems, "\n".join(problems) + "\n" + table
    # Moments the run outlived (load changes between the measurement and the sweep) are no
    # test; almost all must have been real.
    assert sum(not r["ended_before"] for r in runs) >= SIGINT_MOMENTS - 2, table
    # The sweep reached the epochs: some summaries hold completed epochs, some none.
    epochs = [r["summary"]["epochs_completed"] for r in runs if r["summary"]]
    assert min(epochs) == 0 and max(epochs) >= 1, table
