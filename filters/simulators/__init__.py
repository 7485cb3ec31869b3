"""Simulators that serve only experiments and tests (plain numpy; no gymnasium or pymunk).

* :mod:`filters.simulators.car_sim` -- Bailey's car-like landmark-SLAM simulator and its courses.
* :mod:`filters.simulators.grid_raycast` -- a ray caster over a grid map.
"""
