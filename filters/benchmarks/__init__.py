"""Benchmark simulators for the filters (plain numpy; no gymnasium or pymunk).

* :mod:`filters.benchmarks.car_sim` -- Bailey's car-like landmark-SLAM simulator and its courses.
"""
