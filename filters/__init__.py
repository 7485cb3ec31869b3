"""Estimators for 2D robot localization and SLAM: numpy + scipy only.

No simulator, gymnasium, pymunk or torch here: every filter runs on data from a
real robot as well as from :mod:`semreloc_env`.
"""
