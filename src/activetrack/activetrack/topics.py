"""Topic names of the activetrack node graph (plain strings; the core stays ROS-free)."""

CLOCK = "/clock"
PLATFORM_STATES = "/activetrack/platform_states"
BEARING_MEASUREMENTS = "/activetrack/bearing_measurements"
POLAR_MEASUREMENTS = "/activetrack/polar_measurements"
GROUND_TRUTH = "/activetrack/ground_truth"  # evaluators only: tracker and planner never read it
TRACK = "/activetrack/track"
MANOEUVRE_COMMANDS = "/activetrack/manoeuvre_commands"
SENSOR_SELECTION = "/activetrack/sensor_selection"
PLAN_REPORT = "/activetrack/plan_report"
DIAGNOSTICS = "/diagnostics"
TRACK_POSE = "/activetrack/track_pose"  # geometry_msgs/PoseWithCovarianceStamped
PARTICLES = "/activetrack/particles"  # geometry_msgs/PoseArray, subsampled PF cloud
MARKERS = "/activetrack/markers"  # visualization_msgs/MarkerArray

# History depths. The per-epoch topics (measurements, truth, platform states, tracks, commands,
# selections, plan reports) are transient-local with a deep history, so a node or recorder that
# joins late (another process still discovering, a restarted planner) still gets the run so far.
LATCHED_DEPTH = 1024
STREAM_DEPTH = 256
