"""Monte Carlo on a Dask cluster (activetrack.montecarlo.dask): the same numbers as the local
worker processes and as one process, on an in-process cluster of two worker processes; the
tasks carry the client's registrations; a wrong scheduler fails at once, naming --scheduler.
"""

from __future__ import annotations

import dataclasses
import socket
import sys
import textwrap
import time

import numpy as np
import pytest

import activetrack as at
import activetrack.montecarlo.dask as montecarlo_dask
from activetrack.allocator import allocator_tuned
from activetrack.closed_loop.batch import run_batch
from activetrack.montecarlo import even_chunks, parallel_map
from activetrack.montecarlo.dask import SchedulerError, WorkerSetupError, check_scheduler
from activetrack_bringup.cli import main as cli_main
from activetrack_experiments import vanderhook

distributed = pytest.importorskip("distributed", reason="dask/distributed: make setup")

SCENARIO = "scenarios/default.yaml"
TIMING = {"wall_time_s", "decision_time_s"}  # wall-clock figures: the only fields that differ


@pytest.fixture(scope="module")
def cluster():
    """Two single-threaded worker processes (spawned: no state forked from this process)."""
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0"
    ) as local:
        yield local


@pytest.fixture(scope="module")
def address(cluster):
    return cluster.scheduler_address


@pytest.fixture(scope="module")
def scenario():
    return at.load_scenario(SCENARIO).model_copy(update={"steps": 4})


def _closed_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]  # closed again when we return: nothing listens there


def _same_batch(a, b) -> None:
    assert {k: v for k, v in a.to_json().items() if k not in TIMING} == {
        k: v for k, v in b.to_json().items() if k not in TIMING
    }
    for ra, rb in zip(a.records, b.records, strict=True):
        np.testing.assert_array_equal(ra.truth, rb.truth)
        for ta, tb in zip(ra.tracks, rb.tracks, strict=True):
            assert [t.track_id for t in ta.tracks] == [t.track_id for t in tb.tracks]
            for x, y in zip(ta.tracks, tb.tracks, strict=True):
                np.testing.assert_array_equal(x.state, y.state)
                np.testing.assert_array_equal(x.state_cov, y.state_cov)
        np.testing.assert_array_equal(ra.platform_paths, rb.platform_paths)
        assert [d.commands for d in ra.decisions] == [d.commands for d in rb.decisions]
        assert [d.beams for d in ra.decisions] == [d.beams for d in rb.decisions]


def _square(x: int) -> int:
    return x * x


def test_parallel_map_on_dask_keeps_task_order_and_reports_progress(address):
    calls: list[int] = []
    tasks = list(range(23))
    out = parallel_map(_square, tasks, scheduler=address, progress=calls.append)
    assert out == [t * t for t in tasks]
    assert calls == list(range(1, 24))


@pytest.mark.parametrize(
    "name, steps, runs", [(SCENARIO, 4, 5), ("scenarios/mt_bearings_crossing.yaml", 5, 3)]
)
def test_run_batch_dask_equals_local_processes_and_one_process(name, steps, runs, address):
    scenario = at.load_scenario(name).model_copy(update={"steps": steps})
    one = run_batch(scenario, runs=runs, jobs=1)
    local = run_batch(scenario, runs=runs, jobs=2)
    dask = run_batch(scenario, runs=runs, scheduler=address)
    _same_batch(one, local)
    _same_batch(one, dask)
    assert one.runs == dask.runs == runs


def test_run_batch_with_a_connected_client_equals_one_process(scenario, cluster):
    assert allocator_tuned()  # tests/conftest.py, as the command line
    with distributed.Client(cluster, set_as_default=False) as client:
        dask = run_batch(scenario, runs=3, scheduler=client)
        # The workers were spawned, not forked: the chunks told them to tune theirs too.
        assert list(client.run(allocator_tuned).values()) == [True, True]
    _same_batch(run_batch(scenario, runs=3), dask)


def test_a_quick_reproduction_on_dask_equals_local_and_one_process(address):
    kw = dict(runs=60, quick=True)
    one = vanderhook.reproduce(**kw, jobs=1).to_json()
    assert vanderhook.reproduce(**kw, jobs=2).to_json() == one
    assert vanderhook.reproduce(**kw, scheduler=address).to_json() == one


def test_a_reproduction_on_dask_from_the_command_line(address, tmp_path, capsys):
    out = tmp_path / "out"
    argv = ["reproduce", "vanderhook", "--quick", "--runs", "30", "--out", str(out)]
    assert cli_main([*argv, "--jobs", "1", "--json", str(tmp_path / "one.json")]) == 0
    assert cli_main([*argv, "--scheduler", address, "--json", str(tmp_path / "dask.json")]) == 0
    assert (tmp_path / "one.json").read_text() == (tmp_path / "dask.json").read_text()


# --- the registrations travel with the tasks ----------------------------------------------------


def test_a_sensor_kind_registered_in_the_client_only_runs_on_the_workers(address, scenario):
    """The spawned workers import activetrack afresh: only the payload registers the kind."""
    import test_extending_sensor as ext  # a test module: importable on the workers too

    from activetrack.scenarios import registered_kinds, unregister_sensor
    from activetrack.scenarios.schema import Scenario

    already = "range" in registered_kinds()
    at.register_sensor(ext.RangeSensor, ext.RangeSensorConfig)
    try:
        plat = scenario.platforms[1].model_dump()
        plat["sensors"] = [{"id": "s2", "kind": "range", "sigma_r": 5.0}]
        doc = scenario.model_dump()
        doc["platforms"][1] = plat
        sc = Scenario.model_validate(doc)
        _same_batch(run_batch(sc, runs=3), run_batch(sc, runs=3, scheduler=address))
    finally:
        if not already:
            unregister_sensor("range")


def test_a_worker_without_the_plugin_module_says_which(tmp_path, monkeypatch):
    """A chunk whose function lives in a module this 'worker' cannot import: a clear error."""
    from distributed.protocol.pickle import dumps

    (tmp_path / "only_on_the_client.py").write_text(
        textwrap.dedent(
            """
            def cube(x):
                return x ** 3
            """
        )
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    import only_on_the_client

    payload = dumps((only_on_the_client.cube, [2], montecarlo_dask.client_context()))
    assert montecarlo_dask.run_chunk(payload) == [8]
    monkeypatch.delitem(sys.modules, "only_on_the_client")
    monkeypatch.setattr(sys, "path", [p for p in sys.path if p != str(tmp_path)])
    with pytest.raises(WorkerSetupError, match="only_on_the_client.*every worker host"):
        montecarlo_dask.run_chunk(payload)


@pytest.mark.parametrize("name", ["numpy", "numba"])
def test_a_worker_with_other_versions_refuses(name):
    from distributed.protocol.pickle import dumps

    context = montecarlo_dask.client_context()
    assert {"python", "activetrack", "numpy", "scipy", "numba", "llvmlite"} <= set(context.versions)
    versions = {**context.versions, name: "0.0.1"}
    payload = dumps((_square, [3], dataclasses.replace(context, versions=versions)))
    with pytest.raises(WorkerSetupError, match=rf"{name} 0\.0\.1 on the client"):
        montecarlo_dask.run_chunk(payload)


# --- a wrong scheduler fails at once ------------------------------------------------------------


@pytest.mark.parametrize(
    "bad, message",
    [
        ("", "must be an address"),
        ("http://127.0.0.1:8786", "scheme must be one of"),
        ("tcp://127.0.0.1", "scheme://host:port"),
        ("tcp://127.0.0.1:99999", "scheme://host:port"),
        ("tcp://127.0.0.1:0", "scheme://host:port"),
        ("tcp://127.0.0.1:8786/path", "scheme://host:port"),
    ],
)
def test_malformed_addresses_are_refused(bad, message):
    with pytest.raises(SchedulerError, match=message):
        check_scheduler(bad)


def test_nothing_listening_fails_at_once_in_the_library(scenario):
    bad = f"tcp://127.0.0.1:{_closed_port()}"
    start = time.perf_counter()
    with pytest.raises(SchedulerError, match="cannot reach a Dask scheduler"):
        run_batch(scenario, runs=2, scheduler=bad)
    with pytest.raises(SchedulerError, match="cannot reach"):
        vanderhook.reproduce(runs=10, quick=True, scheduler=bad)
    assert time.perf_counter() - start < 10  # the probe's timeout, not Dask's retries


@pytest.mark.parametrize("command", [["batch", SCENARIO], ["reproduce", "valverde", "--quick"]])
def test_the_command_line_names_scheduler(command, capsys):
    bad = f"tcp://127.0.0.1:{_closed_port()}"
    with pytest.raises(SystemExit) as exit_:
        cli_main([*command, "--scheduler", bad])
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert "argument --scheduler: cannot reach a Dask scheduler at" in err
    assert bad in err


def test_a_scheduler_without_workers_fails_with_the_remedy(scenario, monkeypatch, capsys):
    monkeypatch.setattr(montecarlo_dask, "WORKER_WAIT_S", 0.5)
    with distributed.LocalCluster(
        n_workers=0, processes=False, protocol="tcp://", dashboard_address=":0"
    ) as empty:
        with pytest.raises(SchedulerError, match="no worker joined.*dask worker"):
            run_batch(scenario, runs=2, scheduler=empty.scheduler_address)
        assert cli_main(["batch", SCENARIO, "--scheduler", empty.scheduler_address]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: --scheduler: no worker joined tcp://127.0.0.1:")


@pytest.mark.parametrize("n, workers", [(1, 2), (10, 2), (100, 2), (1000, 2), (7, 3), (0, 2)])
def test_even_chunks_cover_the_tasks_in_order_with_sizes_one_apart(n, workers):
    chunks = even_chunks(list(range(n)), workers)
    assert [t for c in chunks for t in c] == list(range(n))
    assert len(chunks) == max(1, min(n, 4 * workers))
    sizes = {len(c) for c in chunks}
    assert max(sizes) - min(sizes) <= 1
