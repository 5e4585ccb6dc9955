"""``activetrack ros graph|echo|hz|param|tf|bag``: the parsers and what each command prints.
Exit codes: 0 done, 1 nothing answered in time, 2 bad input (docs/ros-tools.md).
"""

from __future__ import annotations

import sys
from typing import TYPE_CHECKING

from activetrack_bringup.ros_tools import DISCOVERY_S

if TYPE_CHECKING:  # rclpy loads when a command runs, not when the parser is built
    from activetrack_bringup.ros_tools.session import ToolSession

MAX_DOMAIN_ID = 232  # the highest ROS_DOMAIN_ID ROS 2 allows


def _session(args, name: str) -> ToolSession:
    from activetrack_bringup.ros_tools.session import ToolSession

    return ToolSession(args.domain, args.namespace, name)


def _cmd_graph(args) -> int:
    from activetrack_bringup.ros_tools.introspect import describe_graph, graph_text
    from activetrack_bringup.ros_tools.messages import to_yaml

    with _session(args, "graph") as s:
        s.discover(args.wait)  # let discovery fill in the graph
        graph = describe_graph(s, args.all)
    print(to_yaml(graph) if args.yaml else graph_text(graph))
    return 0


def _cmd_echo(args) -> int:
    from activetrack_bringup.ros_tools.echo import echo

    count = 1 if args.once else args.count
    with _session(args, "echo") as s:
        echo(s, args.topic, count=count, field_path=args.field, wait=args.wait,
             duration=args.duration, out=lambda text: print(text, flush=True))  # fmt: skip
    return 0


def _cmd_hz(args) -> int:
    from activetrack_bringup.ros_tools.hz import hz

    with _session(args, "hz") as s:
        hz(s, args.topic, window=args.window, wait=args.wait, duration=args.duration,
           out=lambda text: print(text, flush=True))  # fmt: skip
    return 0


def _cmd_tf(args) -> int:
    from activetrack_bringup.ros_tools.tf_tree import tf, tree_text

    with _session(args, "tf") as s:
        links, now = tf(s, args.duration)
    clock = "" if now is None else f" at {now:.3f} s"
    print(f"frames ({len(links)} transforms{clock}):")
    print(tree_text(links, now))
    return 0


def _cmd_param(args) -> int:
    from activetrack_bringup.ros_tools import params as p

    with _session(args, "param") as s:
        tool = p.ParamTool(s, args.timeout)
        if args.param_command == "list":
            if args.node:
                print(p.list_text(tool, [args.node]))
            else:
                s.discover()
                nodes = [n for n in s.nodes() if s.in_namespace(n)]
                print(p.list_text(tool, nodes, p.service_names(s)))
        elif args.param_command == "describe":
            print(p.describe_text(tool.describe(args.node, args.names)))
        elif args.param_command == "get":
            print(p.get_text(tool.values(args.node, [args.name])[args.name]))
        elif args.param_command == "set":
            result = tool.set(args.node, args.name, args.value)
            if not result.successful:
                print(f"Setting parameter failed: {result.reason}")
                return 1
            print("Set parameter successful")
        else:  # dump
            print(p.dump_yaml(tool, args.node))
    return 0


def run(args) -> int:
    """Run a ``ros`` subcommand; a ToolError is one ``error:`` line and its exit code."""
    from activetrack_bringup.ros_tools.session import ToolError

    try:
        return args.ros_func(args)
    except ToolError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return exc.code


def _common(parser) -> None:
    from activetrack.argtypes import int_in_range

    parser.add_argument(
        "--namespace", default="", help="resolve relative topic and node names in it"
    )
    parser.add_argument(
        "--domain",
        type=int_in_range(0, MAX_DOMAIN_ID),
        help="DDS domain to join (default ROS_DOMAIN_ID, else 0)",
    )


def _seconds(default: float | None, what: str) -> dict:
    from activetrack.argtypes import float_in_range
    from activetrack.limits import MAX_WALL_SECONDS

    text = f" (default {default:g})" if default is not None else ""
    return {
        "type": float_in_range(0.0, MAX_WALL_SECONDS, lo_inclusive=False),
        "default": default,
        "metavar": "S",
        "help": what + text,
    }


def _add_topic_commands(sub) -> None:
    from activetrack.argtypes import int_in_range

    echo = sub.add_parser("echo", help="print a topic's messages as YAML")
    echo.add_argument("topic")
    echo.add_argument("--once", action="store_true", help="print one message and exit")
    echo.add_argument("--count", type=int_in_range(1, 10**9), help="print N messages and exit")
    echo.add_argument("--field", help="print only this field (dotted: header.stamp.sec)")
    echo.add_argument("--wait", **_seconds(10.0, "wait this long for a publisher"))
    echo.add_argument("--duration", **_seconds(None, "stop after S seconds"))
    echo.set_defaults(func=run, ros_func=_cmd_echo)
    hz = sub.add_parser("hz", help="the rate a topic's messages arrive at")
    hz.add_argument("topic")
    hz.add_argument("--window", type=int_in_range(1, 10**6), default=10_000, help="gaps kept")
    hz.add_argument("--wait", **_seconds(10.0, "wait this long for a publisher"))
    hz.add_argument("--duration", **_seconds(None, "stop after S seconds"))
    hz.set_defaults(func=run, ros_func=_cmd_hz)
    tf = sub.add_parser("tf", help="the frame tree with each latest transform and its age")
    tf.add_argument("--duration", **_seconds(5.0, "listen this long (tf: once an epoch)"))
    tf.set_defaults(func=run, ros_func=_cmd_tf)


def _add_param_commands(sub) -> None:
    param = sub.add_parser("param", help="list, describe, get, set or dump node parameters")
    psub = param.add_subparsers(dest="param_command", required=True)
    parsers = {
        "list": psub.add_parser("list", help="parameter names of a node (default: every node)"),
        "describe": psub.add_parser("describe", help="type, description and constraints"),
        "get": psub.add_parser("get", help="a parameter's value"),
        "set": psub.add_parser("set", help="set a parameter (VALUE read as YAML: 5, 5.0, true)"),
        "dump": psub.add_parser("dump", help="a node's parameters as a params file (YAML)"),
    }
    parsers["list"].add_argument("node", nargs="?")
    for name in ("describe", "get", "set", "dump"):
        parsers[name].add_argument("node", help="node name (relative: in --namespace)")
    parsers["describe"].add_argument("names", nargs="+")
    parsers["get"].add_argument("name")
    parsers["set"].add_argument("name")
    parsers["set"].add_argument("value")
    for p in parsers.values():
        _common(p)
        p.add_argument("--timeout", **_seconds(5.0, "wait this long for each service answer"))
        p.set_defaults(func=run, ros_func=_cmd_param)


def add_ros_parser(sub, add_bag_parser) -> None:
    """``activetrack ros ...`` (``add_bag_parser(subparsers)`` adds ``bag ...`` as today)."""
    ros = sub.add_parser("ros", help="ROS 2 command-line stand-ins: graph, echo, hz, param, tf")
    rsub = ros.add_subparsers(dest="ros_command", required=True)
    graph = rsub.add_parser("graph", help="nodes, topics, types, publishers/subscribers, QoS")
    graph.add_argument("--all", action="store_true", help="also /rosout and /parameter_events")
    graph.add_argument("--yaml", action="store_true", help="print YAML instead of text")
    graph.add_argument(
        "--wait", **_seconds(DISCOVERY_S, "let discovery run at most this long (it stops once "
                             "the graph has not changed for 3.5 s)")
    )  # fmt: skip
    graph.set_defaults(func=run, ros_func=_cmd_graph)
    _add_topic_commands(rsub)
    for name in ("graph", "echo", "hz", "tf"):
        _common(rsub.choices[name])
    _add_param_commands(rsub)
    add_bag_parser(rsub)
