"""Landmark SLAM: range-bearing point landmarks, FastSLAM 1.0/2.0 (+ WOC weight step), EKF-SLAM.

numpy + scipy only. The motion models live in `filters.motion`. Modules:

* `filters.slam.landmarks` -- range-bearing observation model, Jacobians, inverse model, input checks.
* `filters.slam.weight_transforms` -- weight transforms applied before resampling (identity, WOC).
* `filters.slam.association` -- gate settings shared by the filters.
* `filters.slam.fastslam` -- FastSLAM 1.0 / 2.0, vectorised over particles, with subclass hooks.
* `filters.slam.ekf_slam` -- EKF-SLAM baseline.
"""
