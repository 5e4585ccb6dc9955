"""One fully populated example of every msgs_defs type (smoke runs and round-trip tests).

Every field holds a non-default value, so a field lost in transport shows up as a difference.
"""

from __future__ import annotations

from builtin_interfaces.msg import Time
from geometry_msgs.msg import Point, Vector3
from std_msgs.msg import Header

from activetrack_ros import graph as topics
from msgs_defs.msg import (
    BearingMeasurement,
    GroundTruth,
    ManoeuvreCommand,
    Measurement,
    PlanReport,
    PlatformState,
    PolarMeasurement,
    RunMetrics,
    SensorSelection,
    TrackEstimate,
)

MESSAGE_TYPES = (
    BearingMeasurement,
    PolarMeasurement,
    Measurement,
    PlatformState,
    TrackEstimate,
    ManoeuvreCommand,
    SensorSelection,
    PlanReport,
    GroundTruth,
    RunMetrics,  # the evaluator's output: no graph node reads it (not in TOPIC_OF)
)

TOPIC_OF = {
    BearingMeasurement: topics.BEARING_MEASUREMENTS,
    PolarMeasurement: topics.POLAR_MEASUREMENTS,
    Measurement: topics.MEASUREMENTS,
    PlatformState: topics.PLATFORM_STATES,
    TrackEstimate: topics.TRACK,
    ManoeuvreCommand: topics.MANOEUVRE_COMMANDS,
    SensorSelection: topics.SENSOR_SELECTION,
    PlanReport: topics.PLAN_REPORT,
    GroundTruth: topics.GROUND_TRUTH,
}


def _header(seconds: int = 5) -> Header:
    return Header(stamp=Time(sec=seconds, nanosec=250_000_000), frame_id=topics.FIXED_FRAME)


def example_messages() -> list:
    """Return one populated instance of every msgs_defs message type, in MESSAGE_TYPES order.

    The ``graph_auth`` trailer holds a fixed pattern (not a valid tag under any key)."""
    messages = _examples()
    for m in messages:
        m.graph_auth = [(17 * i + 5) % 256 for i in range(16)]
    return messages


def _examples() -> list:
    sensor_pos = Point(x=1800.0, y=2000.0, z=-3.5)
    sensor_vel = Vector3(x=-40.0, y=-40.0, z=0.25)
    return [
        BearingMeasurement(
            header=_header(),
            platform_id="p1",
            sensor_id="s1",
            epoch=1,
            epoch_measurement_count=2,
            sensor_position=sensor_pos,
            sensor_velocity=sensor_vel,
            bearing=-2.356,
            sigma=0.0175,
            detected=True,
            ambiguous=True,
        ),
        PolarMeasurement(
            header=_header(),
            platform_id="p2",
            sensor_id="s3",
            epoch=2,
            epoch_measurement_count=2,
            sensor_position=sensor_pos,
            sensor_velocity=sensor_vel,
            range=1234.5,
            bearing=0.75,
            has_range_rate=True,
            range_rate=-12.5,
            covariance=[100.0, 0.0, 0.0, 0.0, 4.0, 0.0, 0.0, 0.0, 1e-4],
            detected=True,
        ),
        Measurement(
            header=_header(),
            platform_id="p3",
            sensor_id="s4",
            sensor_kind="range",
            epoch=3,
            epoch_measurement_count=3,
            sensor_position=sensor_pos,
            sensor_velocity=sensor_vel,
            z=[1234.5],
            covariance=[4.0],
            detected=True,
        ),
        PlatformState(
            header=_header(),
            platform_id="p1",
            epoch=3,
            sensor_ids=["s1"],
            sensor_kinds=["bearing"],
            position=sensor_pos,
            velocity=sensor_vel,
            heading=-2.356,
            speed=56.57,
            epoch_measurement_count=2,
        ),
        TrackEstimate(
            header=_header(),
            target_id="t1",
            epoch=6,
            filter_kind="pf",
            motion_model="ncv",
            state_names=["x", "xdot", "y", "ydot"],
            state=[1.0, 2.0, 3.0, 4.0],
            covariance=[float(i) for i in range(16)],
            update_count=7,
            missed_detections=2,
            nis=1.5,
            ess=4321.0,
            particle_count=10000,
            particle_samples=[0.5 * i for i in range(8)],
            sample_count=2,
        ),
        ManoeuvreCommand(
            header=_header(),
            platform_id="p1",
            epoch=3,
            heading_change=0.314,
            speed_change=-10.0,
            commanded_heading=-2.042,
            commanded_speed=46.57,
            gate_measurement=True,
            take_measurement=True,
            waypoint=Point(x=10.0, y=-20.0, z=1.0),
            has_waypoint=True,
        ),
        SensorSelection(
            header=_header(),
            epoch=4,
            selected_sensor_ids=["s2"],
            candidate_sensor_ids=["s1", "s2", "s3"],
            predicted_cost=[3.0, 1.0, 2.0],
            criterion="det_pos",
        ),
        PlanReport(
            header=_header(),
            epoch=5,
            cost_kind="pcrlb",
            criterion="b_k",
            search="quadrant",
            horizon=2,
            cost_names=["b_k", "bound_x", "bound_y"],
            predicted_costs=[150.0, 100.0, 111.8],
            evaluations=34,
            planning_wall_time=0.002,
        ),
        GroundTruth(
            header=_header(),
            target_id="t1",
            epoch=9,
            state_names=["x", "xdot", "y", "ydot"],
            state=[100.0, 8.0, -50.0, 6.0],
            position=Point(x=100.0, y=-50.0, z=-2.0),
            velocity=Vector3(x=8.0, y=6.0, z=0.5),
        ),
        RunMetrics(
            header=_header(),
            epoch=4,
            steps=30,
            truth_position=Point(x=100.0, y=-50.0, z=-2.0),
            estimate_position=Point(x=103.0, y=-54.0, z=1.0),
            rmse_x=3.0,
            rmse_y=4.0,
            position_error=5.0,
            bound_x=6.0,
            bound_y=8.0,
            position_bound=10.0,
            mean_rmse_x=2.5,
            mean_rmse_y=3.5,
            mean_bound_x=7.0,
            mean_bound_y=9.0,
            measured_sensor_ids=["s1", "s2"],
        ),
    ]
