"""The activetrack graph on a full ROS 2 Jazzy install (README: On a full ROS 2 install): sim,
tracker and planner, the run's evaluator and recorder, one process each, what
``activetrack run --processes`` starts where launch is not available (not on PyPI).

    ros2 launch activetrack_bringup activetrack.launch.py scenario:=/path/to/default.yaml \\
        [namespace:=graph1] [run:=-1] [mode:=lockstep|free] [rate:=1.0] [filter:=pf]
        [frame_id:=world] [wait_for_subscribers:=0] [wait_for_topic:=tf] [exit:=false]
        [evaluator:=true] [summary:=summary.json] [recorder:=true] [bag:=activetrack_bag]

Every setting of ``activetrack run`` is an argument (tests/setup/test_launch_file.py). There is
no ``use_sim_time``: the nodes stamp with simulated time themselves, and their own timers (the
tracker's epoch_timeout, the free-run tick) must keep wall time, as /clock stands still while
lockstep waits for them. Export the same ``ACTIVETRACK_GRAPH_KEY`` first.
"""

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, EmitEvent, RegisterEventHandler
from launch.conditions import IfCondition
from launch.event_handlers import OnProcessExit
from launch.events import Shutdown
from launch.substitutions import (
    AndSubstitution,
    LaunchConfiguration,
    NotSubstitution,
    PythonExpression,
)
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue

ARGUMENTS = (
    ("scenario", None, "scenario YAML file (absolute, or relative to where ros2 launch runs)"),
    ("namespace", "", "ROS namespace of every node and the graph's topics (default none)"),
    ("run", "-1", "Monte Carlo run index of the seeding (-1: the scenario's seed only)"),
    ("mode", "lockstep", "lockstep (deterministic, the sim waits for commands) or free"),
    ("rate", "1.0", "free mode: simulated seconds per wall second"),
    ("filter", "", "the tracker's filter: ekf, pf or a plugin's (empty: the scenario's)"),
    ("frame_id", "world", "fixed frame of every header and the root of the tf tree"),
    ("wait_for_subscribers", "0", "hold the first epoch until this many outside subscribers"),
    ("wait_for_topic", "", "hold the first epoch until an outside node subscribes to this"),
    ("exit", "false", "end the launch once the run is done"),
    ("evaluator", "true", "start the evaluator (per-epoch RMSE and PCRLB, the summary)"),
    ("summary", "", "the evaluator writes the run's summary.json here (empty: none)"),
    ("recorder", "true", "record the run's bag"),
    ("bag", "activetrack_bag", "the recorder's rosbag2 directory (must not exist yet)"),
)


def _argument(name, default, description):
    if default is None:
        return DeclareLaunchArgument(name, description=description)
    return DeclareLaunchArgument(name, default_value=default, description=description)


def _value(name, value_type):
    return ParameterValue(LaunchConfiguration(name), value_type=value_type)


def _run_readers():
    """The evaluator and recorder this launch starts (by name): the sim holds its first epoch
    until they subscribe, so that they see the run from its start, as under activetrack run,
    which starts them before the graph's nodes."""
    arg = LaunchConfiguration
    started = ["' '.join(n for n, on in (('activetrack_evaluator', '", arg("evaluator"),
               "'), ('activetrack_recorder', '", arg("recorder"),
               "')) if on.lower() in ('true', '1'))"]  # fmt: skip
    return ParameterValue(PythonExpression(started), value_type=str)


def _sim_exits():
    """The sim exits after its last epoch with exit:=true only without an evaluator: a sim
    gone at once would take its latched history from a reader still discovering it."""
    arg = LaunchConfiguration
    return ParameterValue(AndSubstitution(arg("exit"), NotSubstitution(arg("evaluator"))),
                          value_type=bool)  # fmt: skip


def _parameters():
    """Each executable's parameters, by node name (package, executable, parameters)."""
    graph = {"scenario": _value("scenario", str), "run": _value("run", int),
             "frame_id": _value("frame_id", str)}  # fmt: skip
    mode = {"mode": _value("mode", str)}
    sim = {
        **graph, **mode, "rate": _value("rate", float), "exit_when_done": _sim_exits(),
        "wait_for_subscribers": _value("wait_for_subscribers", int),
        "wait_for_topic": _value("wait_for_topic", str), "wait_for_nodes": _run_readers(),
        "expect_tracker": True,  # started below: waited for even while still starting
    }  # fmt: skip
    return {  # the planner plans alike in both modes: it has no mode
        "sim_node": ("sim_node", "sim_node", sim),
        "tracker_node": ("tracker_node", "tracker_node", {**graph, **mode,
                                                         "filter": _value("filter", str)}),
        "planner_node": ("planner_node", "planner_node", graph),
        "activetrack_evaluator": ("activetrack_bringup", "activetrack_evaluator", {
            **graph, "summary": _value("summary", str), "exit_when_done": _value("exit", bool),
        }),
        "activetrack_recorder": ("activetrack_bringup", "activetrack_recorder",
                                 {"bag": _value("bag", str)}),
    }  # fmt: skip


def generate_launch_description():
    arg = LaunchConfiguration
    optional = {"activetrack_evaluator": "evaluator", "activetrack_recorder": "recorder"}
    nodes = {
        name: Node(
            package=package,
            executable=executable,
            name=name,
            namespace=arg("namespace"),
            parameters=[params],
            output="screen",
            **({"condition": IfCondition(arg(optional[name]))} if name in optional else {}),
        )
        for name, (package, executable, params) in _parameters().items()
    }
    # exit:=true ends the launch when the run is done: the evaluator exits once it has the
    # whole run; without an evaluator, when the sim exits after its last epoch.
    done = [
        RegisterEventHandler(
            OnProcessExit(target_action=nodes[target], on_exit=[EmitEvent(event=Shutdown())]),
            condition=IfCondition(AndSubstitution(arg("exit"), when)),
        )
        for target, when in (
            ("activetrack_evaluator", arg("evaluator")),
            ("sim_node", NotSubstitution(arg("evaluator"))),
        )
    ]
    return LaunchDescription([*(_argument(*a) for a in ARGUMENTS), *nodes.values(), *done])
