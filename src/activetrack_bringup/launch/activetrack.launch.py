"""The activetrack graph on a full ROS 2 Jazzy install: simulator, tracker and planner, one
process each (what ``activetrack run --processes`` starts where launch is not available: the
``launch`` packages are not on PyPI).

    ros2 launch activetrack_bringup activetrack.launch.py scenario:=/path/to/default.yaml \\
        [namespace:=graph1] [run:=-1] [mode:=lockstep|free] [frame_id:=world]

``namespace`` puts the three nodes and every topic of the graph (its names are relative) under
/graph1, so several graphs can share a DDS domain. There is no ``use_sim_time`` argument: the
simulator publishes /clock and every message of the graph is stamped with simulated time by
the nodes themselves, while the nodes' own timers (the tracker's epoch_timeout, the free-run
tick) must keep wall time: on /clock, which stands still while lockstep waits for them, they
would never fire. Tools that follow the run (RViz, a recorder) take ``use_sim_time:=true``.
For the graph's writer authentication, export the same ``ACTIVETRACK_GRAPH_KEY`` first.
tests/setup/test_launch_file.py checks this file without launch: it imports launch APIs only,
each executable is a console script of its package, each parameter is one the node declares.
"""

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue

ARGUMENTS = (
    ("scenario", None, "scenario YAML file (absolute, or relative to where ros2 launch runs)"),
    ("namespace", "", "ROS namespace of the three nodes and the graph's topics (default none)"),
    ("run", "-1", "Monte Carlo run index of the seeding (-1: the scenario's seed only)"),
    ("mode", "lockstep", "lockstep (deterministic, the sim waits for commands) or free"),
    ("frame_id", "world", "fixed frame of every header and the root of the tf tree"),
)


def _argument(name, default, description):
    if default is None:
        return DeclareLaunchArgument(name, description=description)
    return DeclareLaunchArgument(name, default_value=default, description=description)


def generate_launch_description():
    arg = LaunchConfiguration
    scenario_and_run = {
        "scenario": ParameterValue(arg("scenario"), value_type=str),
        "run": ParameterValue(arg("run"), value_type=int),
        "frame_id": ParameterValue(arg("frame_id"), value_type=str),
    }
    mode = {"mode": ParameterValue(arg("mode"), value_type=str)}
    parameters = {  # the planner declares no mode
        "sim_node": {**scenario_and_run, **mode},
        "tracker_node": {**scenario_and_run, **mode},
        "planner_node": scenario_and_run,
    }
    nodes = [
        Node(
            package=name,
            executable=name,
            namespace=arg("namespace"),
            parameters=[params],
            output="screen",
        )
        for name, params in parameters.items()
    ]
    return LaunchDescription([*(_argument(*a) for a in ARGUMENTS), *nodes])
