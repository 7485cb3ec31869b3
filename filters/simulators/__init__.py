"""Simulators that serve only experiments and tests (plain numpy; no gymnasium or pymunk).

* :mod:`filters.simulators.car_sim` -- Bailey's car-like landmark-SLAM simulator, its courses, and
  :func:`~filters.simulators.car_sim.run_slam`, the loop that drives a SLAM filter through a run.
* :mod:`filters.simulators.grid_raycast` -- a ray caster over a grid map.
"""
