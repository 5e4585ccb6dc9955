"""The activetrack node graph in one table: topic names, message types and QoS.

Per-epoch topics (measurements, truth, platform states, tracks, commands, selections, plan
reports) are reliable and transient-local with a deep history, so a node or recorder that joins
late (another process still discovering, a restarted planner) still gets the run so far. Their
messages carry the graph's authentication trailer (``activetrack_ros.trust``). The other topics
are streams for people and tools (clock, diagnostics, markers, poses).

Readers keep every sample (KEEP_ALL): with a reliable writer a full reader makes the writer
wait instead of overwriting, so a flood on a topic cannot push the graph's own messages out of
a reader's history; nodes drain their readers fast (foreign messages are dropped on a hash
check before deserialisation).
"""

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

CLOCK = "/clock"
PLATFORM_STATES = "/activetrack/platform_states"
BEARING_MEASUREMENTS = "/activetrack/bearing_measurements"
POLAR_MEASUREMENTS = "/activetrack/polar_measurements"
# Generic measurements (msgs_defs/Measurement): every sensor kind without a typed topic.
MEASUREMENTS = "/activetrack/measurements"
GROUND_TRUTH = "/activetrack/ground_truth"  # evaluators only: tracker and planner never read it
TRACK = "/activetrack/track"
MANOEUVRE_COMMANDS = "/activetrack/manoeuvre_commands"
SENSOR_SELECTION = "/activetrack/sensor_selection"
PLAN_REPORT = "/activetrack/plan_report"
DIAGNOSTICS = "/diagnostics"
TRACK_POSE = "/activetrack/track_pose"  # geometry_msgs/PoseWithCovarianceStamped
PARTICLES = "/activetrack/particles"  # geometry_msgs/PoseArray, subsampled PF cloud
MARKERS = "/activetrack/markers"  # visualization_msgs/MarkerArray

# Every topic of the graph with its type (what `activetrack record` records by default).
GRAPH_TOPICS = {
    CLOCK: "rosgraph_msgs/msg/Clock",
    GROUND_TRUTH: "msgs_defs/msg/GroundTruth",
    PLATFORM_STATES: "msgs_defs/msg/PlatformState",
    BEARING_MEASUREMENTS: "msgs_defs/msg/BearingMeasurement",
    POLAR_MEASUREMENTS: "msgs_defs/msg/PolarMeasurement",
    MEASUREMENTS: "msgs_defs/msg/Measurement",
    TRACK: "msgs_defs/msg/TrackEstimate",
    TRACK_POSE: "geometry_msgs/msg/PoseWithCovarianceStamped",
    PARTICLES: "geometry_msgs/msg/PoseArray",
    MANOEUVRE_COMMANDS: "msgs_defs/msg/ManoeuvreCommand",
    SENSOR_SELECTION: "msgs_defs/msg/SensorSelection",
    PLAN_REPORT: "msgs_defs/msg/PlanReport",
    DIAGNOSTICS: "diagnostic_msgs/msg/DiagnosticArray",
    MARKERS: "visualization_msgs/msg/MarkerArray",
}

# Transient-local per-epoch topics; their messages are authenticated (msgs_defs types).
LATCHED_TOPICS = frozenset(
    {
        BEARING_MEASUREMENTS,
        POLAR_MEASUREMENTS,
        MEASUREMENTS,
        PLAN_REPORT,
        GROUND_TRUTH,
        PLATFORM_STATES,
        TRACK,
        MANOEUVRE_COMMANDS,
        SENSOR_SELECTION,
    }
)

# History depths of the writers: per-epoch topics keep the run for late joiners.
LATCHED_DEPTH = 1024
STREAM_DEPTH = 256


def writer_qos(topic: str) -> QoSProfile:
    """The QoS the graph's publishers offer on ``topic``."""
    if topic in LATCHED_TOPICS:
        return QoSProfile(
            depth=LATCHED_DEPTH,
            reliability=ReliabilityPolicy.RELIABLE,
            durability=DurabilityPolicy.TRANSIENT_LOCAL,
        )
    return QoSProfile(depth=STREAM_DEPTH, reliability=ReliabilityPolicy.RELIABLE)


def reader_qos(topic: str) -> QoSProfile:
    """The QoS the graph's subscriptions request on ``topic`` (KEEP_ALL, see above)."""
    latched = topic in LATCHED_TOPICS
    return QoSProfile(
        history=HistoryPolicy.KEEP_ALL,
        depth=0,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE,
    )


def qos_for(topic: str) -> QoSProfile:
    """QoS for a tool that both reads and writes a topic like the graph does (player, tests)."""
    return writer_qos(topic)
