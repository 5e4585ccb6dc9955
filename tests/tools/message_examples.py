"""One fully populated example of every msgs_defs type (smoke runs and round-trip tests).

Every field holds a non-default value (inside the track array's items too), so a field lost in
transport shows up as a difference.
"""

from __future__ import annotations

import math

from builtin_interfaces.msg import Time
from geometry_msgs.msg import Point, Vector3
from std_msgs.msg import Header

from activetrack_ros import graph as topics
from msgs_defs.msg import (
    BeamCommand,
    GroundTruthArray,
    ManoeuvreCommand,
    PlanReport,
    PlatformState,
    RunMetrics,
    Scan,
    SensorSelection,
    TrackArray,
    TrackItem,
)

MESSAGE_TYPES = (
    Scan,
    PlatformState,
    TrackArray,
    ManoeuvreCommand,
    BeamCommand,
    SensorSelection,
    PlanReport,
    GroundTruthArray,
    RunMetrics,  # the evaluator's output: no graph node reads it (not in TOPIC_OF)
)

TOPIC_OF = {
    Scan: topics.SCANS,
    PlatformState: topics.PLATFORM_STATES,
    TrackArray: topics.TRACKS,
    ManoeuvreCommand: topics.MANOEUVRE_COMMANDS,
    BeamCommand: topics.BEAM_COMMANDS,
    SensorSelection: topics.SENSOR_SELECTION,
    PlanReport: topics.PLAN_REPORT,
    GroundTruthArray: topics.GROUND_TRUTH,
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


def _track_item() -> TrackItem:
    """A confirmed particle track with two posterior samples; its state is not pv (a
    five-entry model), so state and mean differ."""
    return TrackItem(
        track_id=3,
        status=TrackItem.CONFIRMED,
        origin="t1",
        priority=1.5,
        state=[1.0, 2.0, 3.0, 4.0, 0.01],
        state_covariance=[float(i) for i in range(25)],
        mean=[1.0, 2.5, 3.0, 4.5],
        covariance=[float(i) + 0.5 for i in range(16)],
        hits=7,
        misses=2,
        missed_detections=1,
        age=9,
        existence=0.75,
        withheld=True,
        nis=1.5,
        ess=4321.0,
        particle_count=10000,
        samples=[0.5 * i for i in range(10)],
        sample_count=2,
    )


def _examples() -> list:
    sensor_pos = Point(x=1800.0, y=2000.0, z=-3.5)
    sensor_vel = Vector3(x=-40.0, y=-40.0, z=0.25)
    return [
        Scan(
            header=_header(),
            platform_id="p2",
            sensor_id="s3",
            sensor_kind="range_bearing",
            epoch=2,
            epoch_scan_count=2,
            sensor_position=sensor_pos,
            sensor_velocity=sensor_vel,
            fov_centre=0.75,
            fov_width=1.5,
            fov_r_min=10.0,
            fov_r_max=5000.0,
            dim=2,
            detections=[1234.5, 0.75, 2000.0, -0.5],
            covariance=[100.0, 0.0, 0.0, 1e-4],
            clutter_density=1e-5,
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
            epoch_scan_count=2,
        ),
        TrackArray(
            header=_header(),
            epoch=6,
            filter_kind="pf",
            motion_model="circular",
            state_names=["x", "xdot", "y", "ydot", "omega"],
            updates=6,
            tracks=[_track_item()],
            detections=4,
            unassociated=1,
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
        BeamCommand(header=_header(), sensor_id="s2", epoch=4, bearing=-1.25, track_id=3),
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
        GroundTruthArray(
            header=_header(),
            epoch=9,
            target_ids=["t1", "t2"],
            positions=[Point(x=100.0, y=-50.0, z=-2.0), Point(x=-30.0, y=70.0, z=1.0)],
            velocities=[Vector3(x=8.0, y=6.0, z=0.5), Vector3(x=-1.0, y=2.0, z=0.25)],
            state_sizes=[4, 5],
            state_names=["x", "xdot", "y", "ydot", "x", "xdot", "y", "ydot", "omega"],
            states=[100.0, 8.0, -50.0, 6.0, -30.0, -1.0, 70.0, 2.0, 0.02],
        ),
        RunMetrics(
            header=_header(),
            epoch=4,
            steps=30,
            target_ids=["t1", "t2"],
            truth_positions=[Point(x=100.0, y=-50.0, z=-2.0), Point(x=1.0, y=2.0, z=0.5)],
            estimate_positions=[Point(x=103.0, y=-54.0, z=1.0), Point(x=2.0, y=3.0, z=0.5)],
            error_x=[3.0, 1.0],
            error_y=[4.0, 1.0],
            position_error=[5.0, math.sqrt(2.0)],
            bound_x=[6.0, 2.0],
            bound_y=[8.0, 2.0],
            position_bound=[10.0, math.sqrt(8.0)],
            time_avg_rmse_x=[2.5, 1.5],
            time_avg_rmse_y=[3.5, 1.5],
            time_avg_bound_x=[7.0, 2.5],
            time_avg_bound_y=[9.0, 2.5],
            gospa=12.5,
            localisation=27.0,
            missed_targets=1,
            false_tracks=2,
            mean_gospa=11.0,
            measured_sensor_ids=["s1", "s2"],
        ),
    ]
