"""``activetrack ros graph``: nodes, topics with their types, and each topic's publishers and
subscribers with the QoS they offer or request (what ``ros2 node list``, ``ros2 topic list
-t`` and ``ros2 topic info -v`` show together)."""

from __future__ import annotations

from rclpy.qos import DurabilityPolicy, HistoryPolicy, ReliabilityPolicy

from activetrack_bringup.ros_tools.session import ToolSession

# Every node's own plumbing: shown only with --all.
_PLUMBING = ("/rosout", "/parameter_events")


def qos_text(qos) -> str:
    """``reliable transient_local``, and the history where discovery tells it (with Fast DDS
    it does not: ``ros2 topic info -v`` shows it as UNKNOWN too)."""
    reliability = ReliabilityPolicy(qos.reliability).name.lower()
    durability = DurabilityPolicy(qos.durability).name.lower()
    history = {HistoryPolicy.KEEP_ALL: " keep_all", HistoryPolicy.KEEP_LAST: f" keep_last "
               f"{qos.depth}"}.get(qos.history, "")  # fmt: skip
    return f"{reliability} {durability}{history}"


def endpoint_name(info) -> str:
    return info.node_namespace.rstrip("/") + "/" + info.node_name


def describe_graph(session: ToolSession, everything: bool = False) -> dict:
    """``{"nodes": [...], "topics": {name: {"types": [...], "publishers": [[node, qos]],
    "subscribers": [[node, qos]]}}}`` of the graph in the session's namespace (all of it
    without one); ``everything`` adds /rosout and /parameter_events."""
    node = session.node
    own = "/" + node.get_name()
    topics = {}
    for name, types in sorted(node.get_topic_names_and_types()):
        if not session.in_namespace(name) or (name in _PLUMBING and not everything):
            continue
        topics[name] = {
            "types": list(types),
            "publishers": [
                [endpoint_name(i), qos_text(i.qos_profile)]
                for i in node.get_publishers_info_by_topic(name)
                if endpoint_name(i) != own
            ],
            "subscribers": [
                [endpoint_name(i), qos_text(i.qos_profile)]
                for i in node.get_subscriptions_info_by_topic(name)
                if endpoint_name(i) != own
            ],
        }
    nodes = [n for n in session.nodes() if session.in_namespace(n)]
    return {"nodes": nodes, "topics": topics}


def graph_text(graph: dict) -> str:
    lines = [f"nodes ({len(graph['nodes'])}):"]
    lines += [f"  {n}" for n in graph["nodes"]]
    lines.append(f"topics ({len(graph['topics'])}):")
    for name, t in graph["topics"].items():
        lines.append(f"  {name}  [{', '.join(t['types'])}]")
        for role in ("publishers", "subscribers"):
            for endpoint, qos in t[role]:
                lines.append(f"    {role[:-1]:<10} {endpoint}  ({qos})")
    return "\n".join(lines)
