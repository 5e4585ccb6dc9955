"""The ``activetrack`` command line.

activetrack run SCENARIO [--processes] [--mode lockstep|free] [--json PATH]
                [--foxglove [--port P] [--host H]] [--nodes [NAME ...]]
                [--rate R] [--filter NAME] [--wait-for N|TOPIC [--wait-timeout S]]
                                        the ROS node graph, closed loop, with a run folder
                                        (and a live view in Foxglove; --nodes: only these
                                        node processes here, the others on other hosts)
activetrack batch SCENARIO [--runs N] [--jobs J | --scheduler ADDRESS] [--json PATH]
                                        the same closed loop without ROS (the reference), on
                                        local processes or a Dask cluster (docs/dask.md)
activetrack record BAG [--topics T ...] [--duration S]
                                        record graph topics to a rosbag2 directory (MCAP)
activetrack play BAG [--topics T ...] [--rate R] [--skip-damaged]
                                        republish a bag
activetrack bag info BAG                topics, types, counts and damage of a bag (CRC-checked)
activetrack bag retrack BAG --scenario S [--skip-damaged]
                                        replay a run's scans into a fresh tracker
activetrack bag recover BAG             rebuild a readable bag from a damaged/unfinished one
activetrack track DETECTIONS --config C [--skip-damaged]
                                        track recorded detections (CSV, JSON, a bag)
activetrack reproduce NAME [ARGS...]    reproduce a paper's tables (hernandez, ...)
activetrack ros graph|echo|hz|param|tf|bag [--namespace NS] [--domain D]
                                        ROS 2 command-line stand-ins on a running graph
                                        (docs/ros-tools.md)
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import os
import sys
import time
from pathlib import Path

from activetrack.strict_json import write_json
from activetrack_bringup import cli_types, interrupts
from activetrack_bringup.ros_tools.cli import add_ros_parser
from activetrack_bringup.track import add_track_parser

EXPERIMENTS = ("hernandez", "multitarget", "ramdaras", "valverde", "vanderhook")
WAIT_TIMEOUT_S = 60.0  # --wait-for's default --wait-timeout
LAYOUT = "docs/foxglove-layout.json"  # the Foxglove layout of a live run and of a bag
# shown after a run (association: oversize JPDA clusters, tracker.tracks.oversize_cluster)
NOTABLE_COUNTERS = ("rejected", "errors", "dropped", "incompatible_writers", "association")


def _print_summary(s) -> None:
    """A run or batch summary (BatchSummary): each target's time-averaged RMSE against its
    PCRLB, GOSPA, track breaks and swaps, planning cost."""
    n = len(s.target_ids)
    print(f"scenario {s.scenario}: {s.runs} run(s) x {s.steps} steps, {n} target(s)")
    print("  time-averaged RMSE and PCRLB (README: Errors and bounds)")
    for i, tid in enumerate(s.target_ids):
        held = "" if s.association == "known" else f", held {100 * s.held_fraction[i]:5.1f}%"
        print(
            f"  {tid:10s} RMSE x {s.time_avg_rmse_x[i]:9.3f} m y {s.time_avg_rmse_y[i]:9.3f} m, "
            f"PCRLB x {s.time_avg_bound_x[i]:9.3f} m y {s.time_avg_bound_y[i]:9.3f} m{held}"
        )
    print(f"  GOSPA      {s.mean_gospa:9.2f} m (time-averaged)")
    if s.association != "known":
        print(f"  tracks     {s.breaks:.2f} breaks, {s.swaps:.2f} swaps per run")
    print(
        f"  planning   {s.evaluations_per_decision:.1f} evaluations/decision, "
        f"{1e3 * s.decision_time_s:.2f} ms/decision"
    )


def _write_json(path: str, data: dict) -> None:
    try:
        write_json(path, data)
    except OSError as exc:  # checked up front (cli_types.output_file), yet it can still fail
        raise _CommandError(f"--json {path}: {exc.strerror or exc}") from None
    print(f"  summary    {path}")


def _cmd_run(args: argparse.Namespace) -> int:
    started = time.monotonic()
    concluded = []  # run_graph's answer came: it wrote the run's summary
    try:
        return _run(args, concluded)
    except (KeyboardInterrupt, interrupts.Terminated, Exception) as exc:
        code = interrupts.received()
        if isinstance(exc, Exception) and code is None:
            raise  # an error, not a signal
        # An Exception with a signal noted: a C extension wrapped the signal's exception in
        # its own error (pydantic-core building a scenario model gives a SchemaError).
        if concluded:
            raise
        from activetrack_bringup.run_folder import interrupted_before_start, run_dir_for

        code = code or interrupts.exit_code(exc)
        with interrupts.held():  # a second signal must not cut the summary short
            # The scenario's name is not known yet: the default folder takes the file's.
            run_dir = Path(args.out or run_dir_for(Path(args.scenario).stem))
            try:
                interrupted_before_start(run_dir, code, time.monotonic() - started)
                print(f"  INCOMPLETE interrupted before the graph started\n  run folder {run_dir}")
            except OSError as err:
                _error(f"{run_dir}: {err.strerror or err}: no summary written")
        if isinstance(exc, Exception):
            interrupts.check()  # the signal's own exception, for its exit code
        raise


def _run(args: argparse.Namespace, concluded: list) -> int:
    interrupts.check()  # a signal while the command line loaded
    from activetrack.scenarios import ScenarioError
    from activetrack_bringup.progress import Bar, epoch_hook
    from activetrack_bringup.runner import GraphSetupError, RunIncomplete, run_graph

    if args.rate is not None and args.mode != "free":
        return _error("--rate: sim seconds per wall second apply in free mode only (--mode free)")
    if args.wait_timeout is not None and args.wait_for is None:
        return _error("--wait-timeout needs --wait-for")
    try:
        live, view = _start_live_view(args)  # before the run: a port in use fails at once
    except ValueError as exc:  # LiveViewError, a bad namespace
        return _error(exc)
    bar = Bar("run", unit="epoch")  # drawn on a terminal only
    hook = {"during_spin": epoch_hook(bar)} if bar.shown else {}
    try:
        result = run_graph(
            args.scenario,
            run=args.run,
            mode=args.mode,
            processes=args.processes or args.nodes is not None,
            run_dir=args.out,
            record=not args.no_bag,
            plots=not args.no_plots,
            timeout=args.timeout,
            **hook,
            **view,
            namespace=args.namespace,
            nodes=args.nodes,
            sim_params={} if args.rate is None else {"rate": args.rate},
            tracker_params={} if args.filter is None else {"filter": args.filter},
            wait_for=args.wait_for,
            wait_timeout=args.wait_timeout or WAIT_TIMEOUT_S,
            announce=_announce(args),
        )
        concluded.append(True)
        code = 0
    except (ScenarioError, FileExistsError, GraphSetupError) as exc:
        return _error(exc)
    except RunIncomplete as exc:
        concluded.append(True)
        _error(exc)
        result, code = exc.result, exc.exit_code
    finally:
        bar.close()
        if live is not None:
            live.stop()
    mode = "processes" if args.processes or args.nodes is not None else "one process"
    if result.summary is not None:
        _print_summary(result.summary)
        print(f"  decisions  {len(result.summary.records[0].decisions)}")
    if not result.complete:
        print(
            f"  INCOMPLETE {result.status} ({result.detail}) after epoch {result.epochs_completed}"
        )
    print(
        f"  wall time  {result.wall_time_s:.2f} s, real-time factor "
        f"{result.real_time_factor:.1f}x ({mode})"
    )
    for node, counts in result.diagnostics.items():
        notable = {k: v for k, v in counts.items() if k.split(".")[0] in NOTABLE_COUNTERS}
        if notable:
            print(f"  {node}: {notable}")
    foreign = sum(result.foreign.values())
    if foreign:
        print(f"  foreign    {foreign} messages from writers outside the graph dropped")
    if result.restarts:
        print(f"  restarts   {result.restarts}")
    print(f"  run folder {result.run_dir}")
    if args.json:
        _write_json(args.json, result.to_json())
    return code


def _announce(args: argparse.Namespace):
    """The run's ``announce`` hook: where its nodes talk (printed before the graph starts, so
    that ROS tools can join), and what ``--wait-for`` waits for."""

    def announce(network) -> None:
        print(f"  ROS        {network.describe()}", flush=True)
        if args.wait_for is not None:
            print(
                f"  waiting up to {args.wait_timeout or WAIT_TIMEOUT_S:g} s for --wait-for "
                f"{args.wait_for} before the first epoch",
                flush=True,
            )

    return announce


def _start_live_view(args: argparse.Namespace):
    """``--foxglove``: the live view's server, listening already, and the run_graph options
    that add its node to the graph (docs/live-view.md); (None, {}) without it."""
    if not args.foxglove:
        if args.port is not None or args.host is not None or args.foxglove_wait:
            raise ValueError("--port, --host and --foxglove-wait need --foxglove")
        return None, {}
    from activetrack_bringup import live_view
    from activetrack_bringup.runner import check_namespace, remote_key
    from activetrack_ros.trust import GraphKey

    namespace = check_namespace(args.namespace)
    # The run's key: the view shows the graph's own messages only (other hosts': theirs).
    key = remote_key(args.nodes) or GraphKey.generate()
    host = live_view.DEFAULT_HOST if args.host is None else args.host
    port = live_view.DEFAULT_PORT if args.port is None else args.port
    server = live_view.LiveServer(host, port, namespace=namespace)
    try:
        print(f"  live view  {server.url}  (Foxglove: Open connection, layout {LAYOUT})")
        if not live_view.is_loopback(host):
            _warn([f"the live view is served beyond this machine ({host}): anyone who can "
                   "reach the port can watch the run"])  # fmt: skip
        if args.foxglove_wait:
            print(f"  waiting up to {args.foxglove_wait:g} s for a Foxglove client", flush=True)
            server.wait_for_subscriber(args.foxglove_wait)
    except BaseException:  # Ctrl-C while waiting
        server.stop()
        raise
    return server, {"graph_key": key, "before_spin": live_view.attach(server, key, namespace)}


def _add_node_setting_args(run) -> None:
    """``activetrack run ... [--rate R] [--filter NAME] [--wait-for N|TOPIC [--wait-timeout
    S]]``: node settings the launch file takes too (tests/setup/test_launch_file.py)."""
    run.add_argument(
        "--rate",
        type=cli_types.sim_rate,
        help="free mode: sim seconds per wall second (the sim's rate parameter; default 1)",
    )
    run.add_argument(
        "--filter", help="the tracker's filter: ekf, pf or a plugin's (default: the scenario's)"
    )
    run.add_argument(
        "--wait-for",
        metavar="N|TOPIC",
        help="hold the first epoch until N nodes outside the graph subscribe to its topics, or "
        "one subscribes to TOPIC (a viewer that must see the start)",
    )
    run.add_argument(
        "--wait-timeout",
        type=cli_types.timeout,
        metavar="S",
        help=f"--wait-for: fail if they have not joined after S seconds (default "
        f"{WAIT_TIMEOUT_S:g})",
    )


def _add_live_view_args(run) -> None:
    """``activetrack run ... --foxglove [--port P] [--host H] [--foxglove-wait S]``."""
    from activetrack.argtypes import float_in_range, int_in_range
    from activetrack.limits import MAX_WALL_SECONDS

    run.add_argument(
        "--foxglove",
        action="store_true",
        help=f"serve the run live to Foxglove on a WebSocket (layout: {LAYOUT})",
    )
    run.add_argument(
        "--port", type=int_in_range(0, 65535), help="live view port (default 8765; 0: any free)"
    )
    run.add_argument("--host", help="live view address (default 127.0.0.1: this machine only)")
    run.add_argument(
        "--foxglove-wait",
        type=float_in_range(0.0, MAX_WALL_SECONDS),
        default=0.0,
        metavar="S",
        help="wait up to S seconds for a Foxglove client to subscribe before the run starts",
    )


def _cmd_batch(args: argparse.Namespace) -> int:
    from activetrack.closed_loop.batch import run_batch
    from activetrack.scenarios import ScenarioError, load_scenario
    from activetrack_bringup.progress import Bar

    try:
        scenario = load_scenario(args.scenario)
    except ScenarioError as exc:
        return _error(exc)
    with Bar("batch", total=args.runs) as bar, _scheduler_errors():  # bar: on a terminal only
        s = run_batch(
            scenario,
            runs=args.runs,
            jobs=args.jobs,
            progress=bar if bar.shown else None,
            scheduler=args.scheduler,
        )
    _print_summary(s)
    print(f"  wall time  {s.wall_time_s:.2f} s; {s.clamps} clamped commands")
    if args.json:
        _write_json(args.json, s.to_json())
    return 0


class _CommandError(Exception):
    """A failure that ends a command with one ``error:`` line and exit code 2."""


@contextlib.contextmanager
def _scheduler_errors():
    """A Dask cluster that fails once the command runs (no worker joined, a worker without a
    module or with other versions): an ``error: --scheduler ...`` line, exit code 2."""
    from activetrack.montecarlo.dask import SchedulerError, WorkerSetupError

    try:
        yield
    except (SchedulerError, WorkerSetupError) as exc:
        raise _CommandError(f"--scheduler: {str(exc).removeprefix('scheduler: ')}") from None


def _error(exc) -> int:
    """A command's failure: one ``error:`` line on stderr, exit code 2."""
    print(f"error: {exc}", file=sys.stderr)
    return 2


def _warn(lines) -> None:
    for line in lines:
        print(f"warning: {line}", file=sys.stderr)


def _cmd_record(args: argparse.Namespace) -> int:
    import time

    from activetrack_bringup.bag import BagRecorder, recorded_topics
    from activetrack_bringup.bag_io import BagError
    from activetrack_bringup.inprocess import InProcessGraph
    from activetrack_bringup.runner import check_namespace

    try:  # relative (activetrack/track) or absolute (/activetrack/track) names
        topic_types = recorded_topics(args.topics or (), "--topics")
        if Path(args.bag).exists():
            raise ValueError(f"{args.bag} exists already: record into a new path")
        namespace = check_namespace(args.namespace) or None  # None: the node's default
    except ValueError as exc:  # GraphSetupError too
        return _error(exc)
    try:
        with InProcessGraph() as graph:
            recorder = graph.add(
                BagRecorder(args.bag, topic_types, context=graph.context, namespace=namespace)
            )
            print(f"recording {len(topic_types)} topics to {args.bag} (Ctrl-C to stop)")
            end = time.monotonic() + (args.duration if args.duration else float("inf"))
            try:  # signals wait while a chunk is written (interrupts.deferred in the recorder)
                with interrupts.raising():
                    graph.spin_until(lambda: time.monotonic() > end, timeout=float("inf"))
            except (KeyboardInterrupt, interrupts.Terminated):
                pass
            finally:
                recorder.close()
    except BagError as exc:
        return _error(exc)
    if recorder.failed:
        return _error(recorder.failed)
    print(f"recorded {recorder.count} messages")
    return 0


def _cmd_play(args: argparse.Namespace) -> int:
    from activetrack_bringup.bag import BagPlayer
    from activetrack_bringup.inprocess import InProcessGraph

    try:
        with InProcessGraph() as graph:
            options = {"skip_damaged": args.skip_damaged, "context": graph.context}
            player = graph.add(BagPlayer(args.bag, args.topics, args.rate, **options))
            _warn(player.warnings)
            graph.spin_until(
                lambda: (player.play_step(), player.done)[1], timeout=float("inf"), step=0.001
            )
            graph.spin_until(lambda: False, timeout=0.2)  # let reliable deliveries finish
    except ValueError as exc:  # BagError, a bad rate
        return _error(exc)
    print(f"published {player.published} messages from {args.bag}")
    return 0


def _cmd_bag_info(args: argparse.Namespace) -> int:
    from activetrack_bringup.bag import bag_info
    from activetrack_bringup.bag_io import BagError

    try:
        info = bag_info(args.bag)
    except BagError as exc:
        return _error(exc)
    print(f"bag {args.bag}: {info['messages']} messages, {info['duration_s']:.2f} s")
    for topic, t in sorted(info["topics"].items()):
        skipped = f"  (skipped: {t['skipped']})" if "skipped" in t else ""
        print(f"  {topic:<40} {t['type']:<45} {t['count']}{skipped}")
    _warn(d["what"] for d in info["damage"])
    _warn(info["notes"])
    if args.json:
        _write_json(args.json, info)
    if not info["intact"]:
        return _error(
            f"{args.bag} is not intact ({len(info['damage'])} problem(s) above): "
            f"`activetrack bag recover {args.bag}` rewrites it from what verifies"
        )
    return 0


def _cmd_bag_retrack(args: argparse.Namespace) -> int:
    from activetrack_bringup.retrack import retrack

    try:
        r = retrack(
            args.bag,
            args.scenario,
            filter_kind=args.filter,
            run=args.run,
            skip_damaged=args.skip_damaged,
        )
    except (ValueError, OSError) as exc:  # BagError/RetrackError, ScenarioError
        return _error(exc)
    _warn(r.warnings)
    same = "identical to" if r.identical else "NOT identical to"
    print(f"replayed {r.epochs} epochs of {args.bag} into a fresh {r.replayed_filter} tracker")
    print(f"  track arrays {same} the recorded ones")
    print(f"  max |state difference| vs recorded tracks      {r.max_state_difference:.3g}")
    print(f"  max |covariance difference| vs recorded tracks {r.max_covariance_difference:.3g}")
    print("  time-averaged RMSE vs truth (README: Errors and bounds)")
    for tid, (rx, ry), (px, py) in zip(
        r.target_ids, r.recorded_time_avg_rmse, r.replayed_time_avg_rmse, strict=True
    ):
        print(
            f"  {tid:10s} recorded ({r.recorded_filter}) x {rx:.3f} y {ry:.3f} m, "
            f"replayed ({r.replayed_filter}) x {px:.3f} y {py:.3f} m"
        )
    print(f"  GOSPA vs truth  recorded {r.recorded_gospa:.3f} m, replayed {r.replayed_gospa:.3f} m")
    if args.json:
        _write_json(args.json, r.to_json())
    return 0


def _cmd_bag_recover(args: argparse.Namespace) -> int:
    from activetrack_bringup.bag_io import BagError
    from activetrack_bringup.bag_recover import recover

    try:
        r = recover(args.bag)
    except (BagError, OSError) as exc:
        return _error(exc)
    if not r.changed:
        print(f"bag {args.bag} is intact ({r.messages} messages): nothing to recover")
    else:
        print(f"recovered {args.bag}: kept {r.messages} messages on {len(r.kept)} topics")
        for topic, n in sorted(r.kept.items()):
            print(f"  {topic:<40} {r.types[topic]:<45} {n}")
        for path in r.backups:
            print(f"  original kept as {path}")
        for line in r.lost:
            print(f"  lost: {line}")
    if args.json:
        _write_json(args.json, r.to_json())
    return 0


def _cmd_reproduce(args: argparse.Namespace) -> int:
    from activetrack_bringup.progress import Bar

    module = importlib.import_module(f"activetrack_experiments.{args.name}")
    with Bar(f"reproduce {args.name}", unit="task") as bar, _scheduler_errors():
        return int(module.main(args.rest, task_progress=bar if bar.shown else None) or 0)


def _add_bag_parser(sub) -> None:
    """``activetrack bag info | retrack | recover``."""
    bag = sub.add_parser("bag", help="inspect bags and replay them into a tracker")
    bag_sub = bag.add_subparsers(dest="bag_command", required=True)
    info = bag_sub.add_parser("info", help="topics, types, counts and duration of a bag")
    info.add_argument("bag")
    info.add_argument(
        "--json", type=cli_types.output_file, help="write the information to this JSON file"
    )
    info.set_defaults(func=_cmd_bag_info)
    rt = bag_sub.add_parser("retrack", help="replay a run's scans into a fresh tracker")
    rt.add_argument("bag")
    rt.add_argument("--scenario", required=True, help="the scenario the run used")
    rt.add_argument(
        "--filter", help="another registered filter: ekf, pf or a plugin's (default: as run)"
    )
    rt.add_argument("--run", type=cli_types.run_index, help="Monte Carlo run index of the run")
    rt.add_argument(
        "--skip-damaged",
        action="store_true",
        help="retrack the epochs a truncated bag holds (default: refuse a damaged bag)",
    )
    rt.add_argument("--json", type=cli_types.output_file, help="write the report to this JSON file")
    rt.set_defaults(func=_cmd_bag_retrack)
    rec_b = bag_sub.add_parser(
        "recover", help="rebuild a readable bag from a damaged or unfinished one"
    )
    rec_b.add_argument("bag")
    rec_b.add_argument(
        "--json", type=cli_types.output_file, help="write the report to this JSON file"
    )
    rec_b.set_defaults(func=_cmd_bag_recover)


def _add_run_parser(sub) -> None:
    """``activetrack run SCENARIO ...``."""
    run = sub.add_parser("run", help="run the ROS node graph on a scenario, closed loop")
    run.add_argument("scenario", help="scenario YAML file")
    run.add_argument("--processes", action="store_true", help="one OS process per node (DDS)")
    run.add_argument("--mode", choices=("lockstep", "free"), default="lockstep")
    run.add_argument("--run", type=cli_types.run_index, help="Monte Carlo run index (seeding)")
    run.add_argument(
        "--namespace", default="", help="ROS namespace of the graph (several graphs per domain)"
    )
    run.add_argument(
        "--nodes",
        nargs="*",
        choices=("sim", "tracker", "planner"),
        metavar="NAME",
        help="start only these node processes here (sim, tracker, planner; none: evaluate "
        "only), implies --processes; the others run on other hosts (docs/multi-host.md)",
    )
    run.add_argument(
        "--out",
        type=cli_types.output_folder,
        help="run folder (default runs/<scenario>-<timestamp>)",
    )
    run.add_argument("--no-bag", action="store_true", help="do not record the bag")
    run.add_argument("--no-plots", action="store_true", help="do not write the PNG plots")
    run.add_argument(
        "--timeout", type=cli_types.timeout, default=600.0, help="wall seconds (default 600)"
    )
    run.add_argument(
        "--json", type=cli_types.output_file, help="also write the summary to this JSON file"
    )
    _add_node_setting_args(run)
    _add_live_view_args(run)
    run.set_defaults(func=_cmd_run)


def build_parser() -> argparse.ArgumentParser:
    from activetrack.argtypes import add_scheduler_option

    parser = argparse.ArgumentParser(
        prog="activetrack", description=__doc__, formatter_class=argparse.RawTextHelpFormatter
    )
    sub = parser.add_subparsers(dest="command", required=True)

    _add_run_parser(sub)

    batch = sub.add_parser("batch", help="run a scenario closed loop without ROS")
    batch.add_argument("scenario", help="scenario YAML file")
    batch.add_argument("--runs", type=cli_types.runs, default=1, help="seeded Monte Carlo runs")
    batch.add_argument(
        "--jobs",
        type=cli_types.jobs,
        default=1,
        help="worker processes (the results do not depend on it)",
    )
    add_scheduler_option(batch)
    batch.add_argument(
        "--json", type=cli_types.output_file, help="write the summary to this JSON file"
    )
    batch.set_defaults(func=_cmd_batch)

    rec = sub.add_parser("record", help="record graph topics to a rosbag2 directory")
    rec.add_argument("bag", type=cli_types.output_folder, help="output directory (must not exist)")
    rec.add_argument("--topics", nargs="+", help="topics (default: every graph topic)")
    rec.add_argument("--duration", type=cli_types.duration, help="seconds (default: until Ctrl-C)")
    rec.add_argument("--namespace", default="", help="the graph's ROS namespace (default none)")
    rec.set_defaults(func=_cmd_record)

    play = sub.add_parser("play", help="republish a recorded bag")
    play.add_argument("bag")
    play.add_argument("--topics", nargs="+", help="only these topics")
    play.add_argument("--rate", type=cli_types.rate, default=1.0, help="speed factor (default 1)")
    play.add_argument(
        "--skip-damaged",
        action="store_true",
        help="play what verifies of a damaged bag: the chunks around corrupt ones, a truncated "
        "bag's messages up to the cut (default: refuse)",
    )
    play.set_defaults(func=_cmd_play)

    _add_bag_parser(sub)
    add_ros_parser(sub, _add_bag_parser)
    add_track_parser(sub)

    rep = sub.add_parser("reproduce", help="reproduce a paper's tables and figures")
    rep.add_argument("name", choices=EXPERIMENTS)
    rep.add_argument("rest", nargs=argparse.REMAINDER, help="options of the experiment")
    rep.set_defaults(func=_cmd_reproduce)
    return parser


def main(argv: list[str] | None = None) -> int:
    """The command line; ``argv`` None: this process's own (the console script)."""
    # The handlers stay in from the first line to the exit: a signal in the instant after a
    # run finished meets them, not Python's own handler (a traceback) or nothing.
    with interrupts.raising():
        try:
            code, command = _main(argv)
        except (KeyboardInterrupt, interrupts.Terminated) as exc:  # as _main returned
            code, command = interrupts.exit_code(exc), None
        if argv is None and command is _cmd_run:
            # A run has written everything and stopped its processes; Python's own teardown
            # of the loaded modules and the DDS library takes a second or more under load
            # (past the 2 s a stop may take): exit now, with any signal held till then.
            with interrupts.held():
                sys.stdout.flush()
                sys.stderr.flush()
                late = interrupts.received()  # after summary.json: the run finished, then this
                os._exit(code if code or late is None else late)
    return code


def _main(argv: list[str] | None) -> tuple[int, object]:
    from activetrack.allocator import tune_allocator

    args = None
    try:
        # (main's handlers are in: a signal while the modules and parsers load is a Ctrl-C too)
        with interrupts.held():  # raised once the arguments say where a run's summary goes
            args = build_parser().parse_args(argv)
            tune_allocator()  # a command-line process: numpy temporaries stay on the heap
        if args.func is not _cmd_run:
            interrupts.check()
        return args.func(args), args.func
    except _CommandError as exc:
        return _error(exc), args and args.func
    except BrokenPipeError:  # `activetrack bag info BAG | head`: the reader left, fine
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # no error at exit
        return 0, args and args.func
    except (KeyboardInterrupt, interrupts.Terminated) as exc:
        code = interrupts.exit_code(exc)
        print(f"activetrack: interrupted ({interrupts.SIGNAL_NAMES[code]})", file=sys.stderr)
        return code, args and args.func


if __name__ == "__main__":
    sys.exit(main())
