"""The runner's evaluator and recorder as executables of their own, for a graph started by
``ros2 launch`` (launch/activetrack.launch.py) or by hand:

    activetrack_evaluator --ros-args -p scenario:=S [-p run:=N] [-p summary:=PATH]
                                     [-p exit_when_done:=true]
    activetrack_recorder --ros-args -p bag:=DIR [-p topics:='clock tf activetrack/track']

Both take the graph key from ``ACTIVETRACK_GRAPH_KEY`` (without it they trust every writer).
The evaluator logs the summary once the run is complete, writes it to ``summary`` if given
and, with ``exit_when_done``, exits; the recorder finishes its bag when it is stopped.
"""

from __future__ import annotations

import time

from activetrack_bringup.bag import BagRecorder
from activetrack_bringup.evaluator import EvaluatorNode
from activetrack_ros.spin import spin_node
from activetrack_ros.trust import GraphKey


def activetrack_evaluator(**kwargs):
    """The node of the ``activetrack_evaluator`` executable: the evaluator for the scenario
    its parameters name (ValueError on a bad one)."""
    node = EvaluatorNode(None, **kwargs)
    node.started = time.monotonic()
    node.concluded = False
    return node


def conclude(node) -> dict:
    """The summary of a complete run (the runner's code), logged and, if the ``summary``
    parameter names a path, written there as JSON; returns it."""
    from activetrack.strict_json import write_json
    from activetrack_bringup.runner import run_summary  # the node classes: only here

    wall = time.monotonic() - node.started
    summary = run_summary(node.scenario, node.record(wall), wall, node.run_index)
    data = summary.to_json()
    node.get_logger().info(f"run complete: GOSPA {summary.mean_gospa:.3f} m (time-averaged)")
    if node.summary_path:
        write_json(node.summary_path, data)
        node.get_logger().info(f"summary written to {node.summary_path}")
    node.concluded = True
    return data


def _evaluator_done(node) -> bool:
    if node.complete and not node.concluded:
        conclude(node)
    return node.concluded and node.exit_when_done


def evaluator_main(args=None) -> None:
    spin_node(activetrack_evaluator, args, done=_evaluator_done)


def activetrack_recorder(**kwargs) -> BagRecorder:
    """The node of the ``activetrack_recorder`` executable: a recorder configured by its
    parameters, keeping the graph's own messages when ACTIVETRACK_GRAPH_KEY is set
    (ValueError on a bad parameter or key)."""
    return BagRecorder(graph_key=GraphKey.from_environment(), **kwargs)


def recorder_main(args=None) -> None:
    spin_node(activetrack_recorder, args)
