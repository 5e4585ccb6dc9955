"""The activetrack node graph in one table: topic names, message types and QoS.

Topic names are relative, so several graphs share a DDS domain under their namespaces
(README, "Topics, namespaces, frames and QoS"); bags store the resolved names, among which
:func:`find_topic` finds a graph topic whatever the namespace.

Per-epoch topics (:data:`LATCHED_TOPICS`) are reliable and transient-local with a deep
history, so a node or recorder that joins late (another process still discovering, a restarted
planner) still gets the run so far; their messages carry the graph's authentication trailer
(``activetrack_ros.trust``). The other topics are streams for people and tools.

Readers keep every sample (KEEP_ALL): with a reliable writer a full reader makes the writer
wait instead of overwriting, so a flood on a topic cannot push the graph's own messages out of
a reader's history (a foreign KEEP_LAST writer that overwrites its own unacknowledged samples
has them reported lost to the reader: the message-lost event, ``dropped.<Type>``; measured:
5,000 sent to a reader that took none for 6 s, 4,514 received and 486 reported lost). rclpy
offers no history per writer, and a content filter cannot check a keyed tag (its expression
travels in discovery, readable by anyone): the graph's room is the drain rate, so nodes drain
their readers in batches (node_base.subscribe_batched) and drop foreign messages on their
length or a hash before deserialisation.
"""

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

# The default fixed frame (every node's ``frame_id`` parameter); the frame tree: docs/frames.md.
FIXED_FRAME = "world"

# The topics; their types: GRAPH_TOPICS.
CLOCK = "clock"
PLATFORM_STATES = "activetrack/platform_states"
SCANS = "activetrack/scans"  # one per looking sensor and epoch
GROUND_TRUTH = "activetrack/ground_truth"  # for evaluators: tracker and planner never read it
TRACKS = "activetrack/tracks"
MANOEUVRE_COMMANDS = "activetrack/manoeuvre_commands"
BEAM_COMMANDS = "activetrack/beam_commands"  # one per steerable sensor and epoch
SENSOR_SELECTION = "activetrack/sensor_selection"
PLAN_REPORT = "activetrack/plan_report"
DIAGNOSTICS = "diagnostics"
TRACK_POSE = "activetrack/track_pose"  # per confirmed track
PARTICLES = "activetrack/particles"  # subsampled particle clouds
MARKERS = "activetrack/markers"
METRICS = "activetrack/metrics"  # per-epoch errors, PCRLB and GOSPA from the runner's evaluator
TF = "tf"  # platforms, target truth and estimates (docs/frames.md)
TF_STATIC = "tf_static"  # sensors on their platforms, latched

# Every topic of the graph with its type (what `activetrack record` records by default).
GRAPH_TOPICS = {
    CLOCK: "rosgraph_msgs/msg/Clock",
    GROUND_TRUTH: "msgs_defs/msg/GroundTruthArray",
    PLATFORM_STATES: "msgs_defs/msg/PlatformState",
    SCANS: "msgs_defs/msg/Scan",
    TRACKS: "msgs_defs/msg/TrackArray",
    TRACK_POSE: "geometry_msgs/msg/PoseWithCovarianceStamped",
    PARTICLES: "geometry_msgs/msg/PoseArray",
    MANOEUVRE_COMMANDS: "msgs_defs/msg/ManoeuvreCommand",
    BEAM_COMMANDS: "msgs_defs/msg/BeamCommand",
    SENSOR_SELECTION: "msgs_defs/msg/SensorSelection",
    PLAN_REPORT: "msgs_defs/msg/PlanReport",
    DIAGNOSTICS: "diagnostic_msgs/msg/DiagnosticArray",
    MARKERS: "visualization_msgs/msg/MarkerArray",
    METRICS: "msgs_defs/msg/RunMetrics",
    TF: "tf2_msgs/msg/TFMessage",
    TF_STATIC: "tf2_msgs/msg/TFMessage",
}

# The per-epoch topics, transient-local: those of the msgs_defs types (authenticated).
LATCHED_TOPICS = frozenset(t for t, kind in GRAPH_TOPICS.items() if kind.startswith("msgs_defs/"))

# History depths of the writers. Per-epoch topics keep the whole run for late joiners: the
# nodes size them from the scenario (history_depth); LATCHED_DEPTH is the depth of tools that
# do not know the run. TF_STATIC keeps its one message (all static transforms in it).
LATCHED_DEPTH = 1024
STREAM_DEPTH = 256
TF_STATIC_DEPTH = 1
# Upper bound of a sized history: memory, not correctness (a node warns when it applies).
MAX_HISTORY_DEPTH = 1_000_000


def run_history(scenario, steps: int | None = None) -> int:
    """Depth that keeps every per-epoch message of a run: (steps + 1) epochs (``steps``, else
    the scenario's; without steps: LATCHED_DEPTH epochs) times the most messages one topic
    carries per epoch (one per sensor, e.g. scans, or per platform)."""
    steps = steps if steps is not None else scenario.steps
    epochs = LATCHED_DEPTH if steps is None else steps + 1
    sensors = sum(len(p.sensors) for p in scenario.platforms)
    return epochs * max(1, sensors, len(scenario.platforms))


def history_depth(scenario) -> int:
    """The writers' depth for a run: run_history, at most MAX_HISTORY_DEPTH."""
    return min(run_history(scenario), MAX_HISTORY_DEPTH)


def writer_qos(topic: str, depth: int | None = None) -> QoSProfile:
    """The graph's publishers' QoS on ``topic`` (``depth``: per-epoch ones', or LATCHED_DEPTH)."""
    if topic != TF_STATIC and topic not in LATCHED_TOPICS:
        return QoSProfile(depth=STREAM_DEPTH, reliability=ReliabilityPolicy.RELIABLE)
    return QoSProfile(
        depth=TF_STATIC_DEPTH if topic == TF_STATIC else depth or LATCHED_DEPTH,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL,
    )


def reader_qos(topic: str) -> QoSProfile:
    """The QoS the graph's subscriptions request on ``topic`` (KEEP_ALL, see above)."""
    latched = topic in LATCHED_TOPICS or topic == TF_STATIC
    return QoSProfile(
        history=HistoryPolicy.KEEP_ALL,
        depth=0,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE,
    )


qos_for = writer_qos  # for a tool that both reads and writes a topic like the graph does


def graph_topic_of(name: str) -> str | None:
    """The graph topic a resolved name like ``/g1/activetrack/tracks`` stands for, or None."""
    for topic in GRAPH_TOPICS:
        if name == topic or name == "/" + topic or name.endswith("/" + topic):
            return topic
    return None


def find_topic(names, topic: str) -> str | None:
    """The one name among ``names`` (e.g. a bag's topics) that is graph topic ``topic`` under
    some namespace; None if there is none. ValueError if several namespaces hold it."""
    found = sorted(n for n in names if graph_topic_of(n) == topic)
    if len(found) > 1:
        raise ValueError(f"several namespaces hold {topic}: {found}")
    return found[0] if found else None
