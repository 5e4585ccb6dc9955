"""The graph across two hosts: two network namespaces joined by a veth link.

Host A runs the runner (evaluator) and the sim node (``run_graph(..., nodes=("sim",))``, as
``activetrack run --nodes sim`` does), host B the tracker and planner nodes from their console
scripts, as docs/multi-host.md tells a user to. Each namespace holds only ``lo`` and its end of
the veth, so DDS discovery and data can only cross that link; Fast DDS is held to UDPv4 (a
safeguard: /dev/shm is common to both, so its shared-memory transport could bypass the link;
measured, it carried nothing between them even when allowed). The
lockstep closed loop must equal ``batch`` exactly, once with multicast discovery and once on a
link without multicast, found by ``ROS_STATIC_PEERS``.

Needs root and iproute2 (``ip netns``): skipped, with the reason, where namespaces cannot be
made (an unprivileged container). Run as a script, this file is host A's side of a run.
"""

from __future__ import annotations

import json
import os
import re
import secrets
import shutil
import signal
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

SCENARIO = "tests/ros/data/short_two_sensors.yaml"
ADDRESSES = {"a": "10.213.15.1", "b": "10.213.15.2"}  # a /30 of their own on the link
RUN_TIMEOUT_S = 40.0
pytestmark = [pytest.mark.ros, pytest.mark.slow]

_unavailable: list[str] = []  # why namespaces cannot be made here, once known


@dataclass
class Hosts:
    """Two namespaces (``ns``: host -> name) joined by a veth pair (``dev``: host -> name)."""

    ns: dict[str, str]
    dev: dict[str, str]

    def ip(self, host: str, *args: str) -> str:
        return _ip("-n", self.ns[host], *args)

    def interfaces(self, host: str) -> set[str]:
        lines = self.ip(host, "-o", "link", "show").splitlines()
        return {line.split(":")[1].strip().split("@")[0] for line in lines}

    def flags(self, host: str) -> set[str]:
        line = self.ip(host, "-o", "link", "show", "dev", self.dev[host])
        return set(line.split("<", 1)[1].split(">", 1)[0].split(","))

    def bytes_received(self, host: str) -> int:
        (link,) = json.loads(self.ip(host, "-j", "-s", "link", "show", "dev", self.dev[host]))
        return int(link["stats64"]["rx"]["bytes"])


def _ip(*args: str) -> str:
    done = subprocess.run(["ip", *args], capture_output=True, text=True, timeout=10)
    if done.returncode:
        raise OSError(f"ip {' '.join(args)}: {done.stderr.strip()}")
    return done.stdout


def _probe() -> str | None:
    """Why two simulated hosts cannot be made here (None: they can)."""
    if not sys.platform.startswith("linux"):
        return "network namespaces are Linux only"
    if os.geteuid() != 0:
        return "network namespaces need root (ip netns add)"
    if shutil.which("ip") is None:
        return "no ip command (iproute2)"
    return None


def _names(tag: str) -> dict[str, str]:
    """The namespaces of a test run: ``at2h-<pid of the test process>-<tag>-<host>``."""
    return {h: f"at2h-{os.getpid()}-{tag}-{h}" for h in "ab"}


def _make_hosts(tag: str, multicast: bool) -> Hosts:
    ns = _names(tag)
    dev = {h: f"at2h{tag}{h}" for h in "ab"}  # interface names: at most 15 characters
    hosts = Hosts(ns, dev)
    for h in "ab":
        _ip("netns", "add", ns[h])
    _ip("link", "add", dev["a"], "type", "veth", "peer", "name", dev["b"])
    for h in "ab":
        _ip("link", "set", dev[h], "netns", ns[h])
        hosts.ip(h, "addr", "add", f"{ADDRESSES[h]}/30", "dev", dev[h])
        hosts.ip(h, "link", "set", "lo", "up")
        hosts.ip(h, "link", "set", dev[h], "up")
        if not multicast:  # no group can be joined: multicast discovery reaches nobody
            no_groups = "echo 0 > /proc/sys/net/ipv4/igmp_max_memberships"
            _ip("netns", "exec", ns[h], "sh", "-c", no_groups)
    return hosts


def _remove_namespaces(names) -> None:
    """Delete namespaces (a veth goes with its namespace), ignoring those not there."""
    for name in names:
        subprocess.run(["ip", "netns", "del", name], capture_output=True, timeout=10)


def _remove_stale() -> None:
    """The namespaces of earlier test runs that were killed before their clean-up (their
    process is gone): nothing runs in them any more (their processes died with the test)."""
    listed = subprocess.run(["ip", "netns", "list"], capture_output=True, text=True, timeout=10)
    stale = []
    for line in listed.stdout.splitlines():
        match = re.fullmatch(r"(at2h-(\d+)-[0-9a-f]+-[ab])( .*)?", line.strip())
        if match and not Path(f"/proc/{match.group(2)}").exists():
            stale.append(match.group(1))
    _remove_namespaces(stale)


@pytest.fixture(params=["multicast", "static_peers"])
def two_hosts(request):
    """Two simulated hosts, removed after the test, whatever happens."""
    if not _unavailable:
        _unavailable.append(_probe() or "")
        if not _unavailable[0]:
            _remove_stale()
    if _unavailable[0]:
        pytest.skip(_unavailable[0])
    tag = secrets.token_hex(3)
    try:
        try:
            hosts = _make_hosts(tag, multicast=request.param == "multicast")
        except OSError as exc:  # e.g. an unprivileged container: say so, once
            _unavailable[0] = f"cannot make two network namespaces joined by a veth: {exc}"
            pytest.skip(_unavailable[0])
        yield request.param, hosts
    finally:
        _remove_namespaces(_names(tag).values())


def _env(static_peer: str | None) -> dict[str, str]:
    """A host's ROS environment: the test's own domain, UDP only, and discovery by multicast
    on the subnet, or (``static_peer``: the other host's address) by unicast to localhost and
    that peer only, as on a network without multicast."""
    env = dict(os.environ)
    env.pop("_ROS_WHEELS_BOOTSTRAP_COMPLETE", None)  # each child re-bootstraps the wheels
    env.pop("ROS_STATIC_PEERS", None)
    env.update(
        ROS_DOMAIN_ID=os.environ["ROS_DOMAIN_ID"],  # tests/conftest.py: unique per test run
        ROS_AUTOMATIC_DISCOVERY_RANGE="SUBNET",
        FASTDDS_BUILTIN_TRANSPORTS="UDPv4",
    )
    if static_peer is not None:
        env.update(ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", ROS_STATIC_PEERS=static_peer)
    return env


def _spawn(hosts: Hosts, host: str, argv: list[str], env: dict, log: Path) -> subprocess.Popen:
    """``argv`` in a host's namespace, killed by the kernel if this process dies (the
    runner's launcher: PR_SET_PDEATHSIG, kept across the exec into ``ip`` and the node)."""
    from activetrack_bringup.supervisor import _LAUNCHER

    ip = [shutil.which("ip") or "/usr/sbin/ip", "netns", "exec", hosts.ns[host], *argv]
    with open(log, "wb") as out:
        return subprocess.Popen(
            [sys.executable, "-S", "-c", _LAUNCHER, str(os.getpid()), *ip],
            env=env,
            stdout=out,
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )


def _signal(proc: subprocess.Popen, sig: int) -> None:
    """``sig`` to the process group the test started (its own session), if still there."""
    try:
        os.killpg(proc.pid, sig)
    except ProcessLookupError:
        pass


def _stop(procs: list[subprocess.Popen]) -> None:
    for p in procs:
        if p.poll() is None:
            _signal(p, signal.SIGTERM)
    for p in procs:
        try:
            p.wait(timeout=5)
        except subprocess.TimeoutExpired:
            _signal(p, signal.SIGKILL)
            p.wait()


def _tail(path: Path, lines: int = 15) -> str:
    text = path.read_text(errors="replace") if path.exists() else ""
    return "\n".join(text.splitlines()[-lines:])


def _run_two_hosts(hosts: Hosts, variant: str, tmp_path: Path) -> tuple[dict, dict]:
    """Host B's tracker and planner first, then host A's runner with its sim; host A's
    results (arrays, summary) once it returns."""
    bindir = Path(sys.executable).parent
    scenario = str(Path(SCENARIO).resolve())
    peers = variant == "static_peers"
    key = {"ACTIVETRACK_GRAPH_KEY": secrets.token_hex(32)}
    env_a = {**_env(ADDRESSES["b"] if peers else None), **key}
    env_b = {**_env(ADDRESSES["a"] if peers else None), **key}
    params = ["--ros-args", "-p", f"scenario:={scenario}", "-p", "run:=-1"]
    commands = {
        "tracker": ("b", [str(bindir / "tracker_node"), *params, "-p", "mode:=lockstep"]),
        "planner": ("b", [str(bindir / "planner_node"), *params]),
        "runner": ("a", [sys.executable, __file__, scenario, str(tmp_path / "out")]),
    }
    procs = []
    try:
        for name, (host, argv) in commands.items():
            env = env_a if host == "a" else env_b
            procs.append(_spawn(hosts, host, argv, env, tmp_path / f"{name}.log"))
        runner = procs[-1]
        try:
            runner.wait(timeout=RUN_TIMEOUT_S + 15)
        except subprocess.TimeoutExpired:
            pass  # returncode None: fails below, with the logs
        logs = {name: _tail(tmp_path / f"{name}.log") for name in commands}
        assert runner.returncode == 0, f"host A's runner failed: {logs}"
    finally:
        _stop(procs)
    out = tmp_path / "out"
    arrays = dict(np.load(out / "arrays.npz"))
    return arrays, json.loads((out / "summary.json").read_text())


def test_the_graph_on_two_hosts_equals_batch(two_hosts, tmp_path):
    from activetrack.closed_loop.batch import run_batch
    from activetrack.scenarios import load_scenario

    variant, hosts = two_hosts
    for h in "ab":  # nowhere else for DDS to go: the loopback and the link
        assert hosts.interfaces(h) == {"lo", hosts.dev[h]}
        assert {"UP", "MULTICAST"} <= hosts.flags(h)  # blocked, for static_peers, by sysctl
    received = {h: hosts.bytes_received(h) for h in "ab"}
    arrays, summary = _run_two_hosts(hosts, variant, tmp_path)
    batch = run_batch(load_scenario(SCENARIO), runs=1)
    b = batch.records[0]
    track_state, track_cov = b.track_series()
    want = {"truth": b.truth, "platform_paths": b.platform_paths}
    want |= {"track_state": track_state, "track_cov": track_cov}
    for name, value in want.items():  # bit for bit
        np.testing.assert_array_equal(arrays[name], value, err_msg=name)
    costs = [d.report.predicted_costs for d in b.decisions]
    np.testing.assert_array_equal(arrays["predicted_costs"], costs)
    assert summary["time_avg_rmse_x"] == batch.time_avg_rmse_x
    assert summary["time_avg_bound_y"] == batch.time_avg_bound_y
    assert summary["mean_gospa"] == batch.mean_gospa
    assert summary["status"] == "complete" and summary["epochs_completed"] == 8
    assert sum(summary["foreign_messages_dropped"].values()) == 0
    # Host B's nodes reported over the link: the evaluator on host A holds their counters.
    diagnostics = summary["diagnostics"]
    assert diagnostics["tracker"]["received.Scan"] == 2 * 8
    assert diagnostics["planner"]["decisions"] == 8
    # Everything crossed the veth: host A received host B's tracks (300 particle samples of 4
    # doubles each, every epoch) and host B the scans.
    assert hosts.bytes_received("a") - received["a"] > 9 * 300 * 4 * 8
    assert hosts.bytes_received("b") > received["b"]
    for h in "ab":
        assert hosts.interfaces(h) == {"lo", hosts.dev[h]}


# --- the runner's side of it, on this host only --------------------------------------------


def test_nodes_on_other_hosts_need_the_shared_domain_and_key(
    tmp_path, monkeypatch, capsys, localhost_discovery
):
    from activetrack_bringup.cli import main as cli_main

    monkeypatch.delenv("ACTIVETRACK_GRAPH_KEY", raising=False)
    out = tmp_path / "run"
    assert cli_main(["run", SCENARIO, "--nodes", "sim", "--out", str(out)]) == 2
    assert "set ACTIVETRACK_GRAPH_KEY to the same 64 hex digits" in capsys.readouterr().err
    monkeypatch.setenv("ACTIVETRACK_GRAPH_KEY", "abc")
    assert cli_main(["run", SCENARIO, "--nodes", "sim", "--out", str(out)]) == 2
    assert "must be 64 hex digits" in capsys.readouterr().err
    monkeypatch.delenv("ROS_DOMAIN_ID")  # the pid-derived default would differ between hosts
    assert cli_main(["run", SCENARIO, "--nodes", "tracker", "planner", "--out", str(out)]) == 2
    assert "sim node(s) run on another host: set ROS_DOMAIN_ID" in capsys.readouterr().err
    assert not out.exists()


def test_nodes_are_chosen_among_the_graphs_with_processes(tmp_path, localhost_discovery):
    from activetrack_bringup.runner import GraphSetupError, run_graph

    with pytest.raises(GraphSetupError, match="needs --processes"):
        run_graph(SCENARIO, run_dir=tmp_path / "a", nodes=("sim",))
    with pytest.raises(GraphSetupError, match=r"unknown nodes \['tracer'\]"):
        run_graph(SCENARIO, run_dir=tmp_path / "b", processes=True, nodes=("tracer",))


def test_a_run_whose_other_hosts_never_come_times_out_and_says_which(
    tmp_path, monkeypatch, localhost_discovery
):
    from activetrack_bringup.runner import RunIncomplete, run_graph

    monkeypatch.setenv("ACTIVETRACK_GRAPH_KEY", secrets.token_hex(32))
    with pytest.raises(RunIncomplete) as info:
        run_graph(SCENARIO, run_dir=tmp_path, processes=True, nodes=("sim",), record=False,
                  plots=False, timeout=1.0)  # fmt: skip
    result = info.value.result
    assert result.status == "timeout" and result.epochs_completed == 0
    assert "['planner_node', 'tracker_node'] of other hosts did not join" in result.detail
    assert not result.restarts and json.loads((tmp_path / "summary.json").read_text())


def _host_a(scenario: str, out: str) -> int:
    """Host A's side: the runner with the sim only; the arrays and the summary to ``out``."""
    from activetrack_bringup.runner import run_graph

    result = run_graph(scenario, run_dir=out, processes=True, nodes=("sim",), record=False,
                       plots=False, timeout=RUN_TIMEOUT_S)  # fmt: skip
    record = result.summary.records[0]
    track_state, track_cov = record.track_series()
    np.savez(
        Path(out) / "arrays.npz",
        truth=record.truth,
        platform_paths=record.platform_paths,
        track_state=track_state,
        track_cov=track_cov,
        predicted_costs=np.array([tuple(d.report.predicted_costs) for d in record.decisions]),
    )
    return 0


if __name__ == "__main__":
    sys.exit(_host_a(*sys.argv[1:]))
