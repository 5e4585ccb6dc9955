"""Upper (and a few lower) bounds on every size and magnitude a user can give: one place.

Scenario files (:mod:`activetrack.scenarios.schema`) and the numbers of the command lines
(:mod:`activetrack.argtypes`, ``activetrack_bringup.cli_types``) are checked against these.
They are generous: no real scenario comes near them (the papers' values are given for
comparison). They exist so that a malformed or hostile input fails at once with a message
naming the field and the limit, instead of overflowing floats, exhausting memory or running
for days. Units: metres, seconds, radians.
"""

import math

# --- names -------------------------------------------------------------------------------------
MAX_NAME_LENGTH = 100  # scenario name: it names the run folder
MAX_ID_LENGTH = 64  # platform and sensor ids
MAX_DESCRIPTION_LENGTH = 10_000
MAX_SEED = 2**63 - 1  # seeds and Monte Carlo run indices (a ROS integer parameter is int64)

# --- time --------------------------------------------------------------------------------------
MIN_DT, MAX_DT = 1e-6, 1e6  # s between epochs (papers: 1-5 s)
MAX_STEPS = 1_000_000  # epochs (papers: 30-600)
MAX_DURATION = 1e9  # s, dt * steps: ROS stamps hold int32 seconds (2.1e9)

# --- geometry and kinematics -------------------------------------------------------------------
MAX_POSITION = 1e9  # m, |x| and |y| of any state (papers: <= 1e4)
MAX_RANGE = 1e10  # m, r_min, a finite r_max, sigma_r (the diagonal of the position box)
MAX_SPEED = 1e6  # m/s, velocity components, v_max, dv_max, sigma_rr, sigma_v (papers: <= 200)
MAX_ACCELERATION = 1e6  # m/s^2, a_max, sigma_x, sigma_y (papers: <= 10)
MAX_Q = 1e6  # m^2/s^3, NCV process noise PSD (papers: 1e-8 to 2.5e-5)
MAX_TURN_RATE = 1e3  # rad/s, omega, psi_rate_max, sigma_omega (papers: <= 0.16)
MAX_ANGLE = 1e3  # rad, an angle state (psi) before wrapping
MIN_SIGMA = 1e-9  # m, rad or m/s: smallest measurement noise (R must stay invertible)
MAX_BEARING_SIGMA = 2.0 * math.pi  # rad
MIN_PRIOR_VARIANCE = 1e-12  # smallest eigenvalue of the prior covariance (papers: >= 1e-6)
MAX_PRIOR_VARIANCE = 1e18  # largest entry of the prior covariance (MAX_POSITION squared)

# --- sizes of the scenario ---------------------------------------------------------------------
MAX_PLATFORMS = 100  # papers: <= 3
MAX_SENSORS = 100  # in total over all platforms (papers: <= 3)
MAX_STATE_DIM = 5  # entries of a prior mean (the circular model has 5)
# Targets of a multi-target scenario (benchmarks/step_profile.py on 2 shared cores: 1,000
# targets spread over 121 radars, 20 false alarms per scan and radar, ~5,900 live tracks: 1.7 s
# per epoch in the tracker).
MAX_TARGETS = 1_000
# Mean false alarms per scan over a sensor's whole field of view: the clutter density times the
# field's volume in measurement units (typical radar/sonar: 1-50).
MAX_CLUTTER_PER_SCAN = 10_000.0
MAX_CLUTTER_DENSITY = 1e12  # false alarms per unit of z (per rad, per m rad)

# --- tracker -----------------------------------------------------------------------------------
# 1,000,000 must stay allowed: the filter benchmarks run the particle filter with that many.
MAX_PARTICLES = 1_000_000  # papers: 10,000
# A planner that works from the particle cloud inverts its covariance; with fewer particles
# resampling soon leaves too few distinct ones for that (about 1 in 5 runs with 50).
MIN_PARTICLES_FOR_PLANNING = 100
MAX_ROUGHENING = 100.0  # Gordon's K (typical: 0.2)
# Live tracks of the multi-target tracker (tentative ones included): ``tracker.tracks.max_tracks``
# may go this high. The step's cost grows with the tracks in each scan's view, not with all
# pairs: ~0.3 ms per live track and epoch measured up to 5,900 tracks (above), so a few seconds
# per epoch at the limit, and a few kB of memory per track.
MAX_TRACKS = 10_000
# Detections in one scan: Poisson clutter of mean <= MAX_CLUTTER_PER_SCAN stays below twice its
# mean (by ~100 standard deviations at the limit), plus one per target. The tracker refuses a
# scan with more (its gate holds tracks x detections pairs).
MAX_SCAN_DETECTIONS = int(2 * MAX_CLUTTER_PER_SCAN) + MAX_TARGETS
MAX_GATE_SIGMAS = 10.0  # gate radius in innovation standard deviations (typical: 3-4)

# --- planner -----------------------------------------------------------------------------------
MAX_SAMPLES = 100_000  # planner_samples, mc_samples (papers: 1,000)
MAX_HORIZON = 10  # epochs (papers: 1-2)
MAX_GRID_SIZE = 1001  # points per side (Hernandez: 101)
MAX_SURVEILLANCE_CELLS = 250_000  # cells of the planner's undetected-target grid
MAX_QUADRANT_DIVISIONS = 50  # also the patience; the square's side is 2^-50 by then (paper: 6)
MAX_SECTOR_LEVELS = 30  # the sector's side is 3^-30 by then (Ramdaras: 5)
MAX_SENSOR_ITERATIONS = 100  # passes over the platforms (Hernandez: 10)
# Cost evaluations of one platform's search over the whole horizon (per-stage count to the
# power of the horizon for the nested searches): 1e7 take minutes per decision (Hernandez's
# 3-sensor two-step case: 1,156 per platform).
MAX_SEARCH_EVALUATIONS = 10_000_000
# Target samples x candidate positions scored in one batch: about 1 GB of memory at the limit
# (the default 101 x 101 grid scores 2,048 candidates per batch against 1,000 samples: 2e6).
MAX_PLANNER_BATCH = 25_000_000
MAX_DWELL = 1e6  # s, cautious t_m (Vander Hook: 60)
MAX_MEASUREMENTS = 1_000_000  # cautious max_measurements

# --- command lines -----------------------------------------------------------------------------
MAX_RUNS = 100_000  # Monte Carlo runs (papers: 100-4,000)
MAX_JOBS = 256  # worker processes
MAX_WALL_SECONDS = 1e7  # s, --timeout and --duration (116 days)
MAX_RATE = 1e6  # bag playback speed factor
MIN_RATE = 1e-3  # bag playback speed factor: a bag's second in at most 1,000 s
# Monte Carlo runs x epochs held in memory at once by a vectorised experiment (Valverde's
# filters keep (epochs, runs, state) arrays: about 1 GB at the limit; default 1,000 x 252).
MAX_RUN_EPOCHS = 25_000_000
