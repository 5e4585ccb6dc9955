"""Multi-target active tracking in clutter: the loop of a scenario with a ``targets:`` list.

- :mod:`.data`: scans, track sets, decisions and the run record;
- :mod:`.simulator`: targets, unlabelled detections with clutter, beams;
- :mod:`.tracker`: JPDA-EKF (or clutter-aware particle filters) with M-of-N track management;
- :mod:`.planner`: manoeuvres against every track and beam-to-track assignment;
- :mod:`.loop`: the closed loop and Monte Carlo batches;
- :mod:`.evaluation`: OSPA / GOSPA over time, track breaks and swaps, per-target RMSE and bound.
"""
