"""Simulators that serve only experiments and tests (plain numpy; no gymnasium or pymunk).

* `filters.simulators.car_sim` -- Bailey's car-like landmark-SLAM simulator, its courses, and
  `run_slam`, the loop that drives a SLAM filter through a run.
* `filters.simulators.grid_raycast` -- a ray caster over a grid map.
"""
