"""Scan containers: what a range sensor hands to a filter.

A scan is taken by a sensor mounted at ``sensor_pose = (x m, y m, theta rad)`` in the
robot frame (default ``(0, 0, 0)``: at the robot centre, facing the heading). Beam
angles are in the *sensor* frame, radians, counter-clockwise; beam ``i`` with range
``r`` ends at ``sensor_pose ⊕ (r cos a_i, r sin a_i)`` in the robot frame.

Per beam:

* ``range_min_m <= r < range_max_m``: a return (used by the measurement models and mapping);
* ``r >= range_max_m``: no return: skipped by the measurement models; mapping clears
  the cells up to the limit (see `filters.mapping.occupancy.OccupancyParams`);
* ``r < range_min_m``: invalid, skipped everywhere.

`LaserScan.from_ros` builds a scan from the fields of a ROS ``sensor_msgs/LaserScan``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from filters.arrays import frozen_array
from filters.numbers import is_int_dtype, is_real


def _checked_sensor_pose(sensor_pose, what: str) -> np.ndarray:
    sp = frozen_array(sensor_pose, np.float64).reshape(-1)
    if sp.shape != (3,) or not np.all(np.isfinite(sp)):
        raise ValueError(f"{what}: sensor_pose must be 3 finite numbers (x m, y m, theta rad), got {sensor_pose!r}")
    return sp


_AT_ROBOT_CENTRE = np.zeros(3)
_AT_ROBOT_CENTRE.setflags(write=False)


def _handed_over(scan, **arrays) -> None:
    """Set a new scan's fields without `_checked_beams`' checks and copies (`LaserScan.from_simulator`,
    `SemanticScan.from_simulator`): the arrays are made read-only in place, not copied."""
    for name, value in arrays.items():
        if isinstance(value, np.ndarray):
            value.setflags(write=False)
        object.__setattr__(scan, name, value)


def beam_endpoints(ranges: np.ndarray, angles: np.ndarray, sensor_pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Robot-frame end points ``(x (B,), y (B,))`` of beams with ``ranges`` / sensor-frame ``angles``.

    With ``sensor_pose == (0, 0, 0)`` this is exactly ``(r cos a, r sin a)`` (no extra rounding).
    """
    r = np.asarray(ranges, dtype=np.float64)
    a = np.asarray(angles, dtype=np.float64)
    sx, sy, st = (float(v) for v in sensor_pose)
    if st == 0.0:
        x, y = r * np.cos(a), r * np.sin(a)
    else:
        x, y = r * np.cos(a + st), r * np.sin(a + st)
    if sx != 0.0 or sy != 0.0:
        x, y = x + sx, y + sy
    return x, y


def _checked_beams(ranges, angles, range_max_m: float, what: str) -> tuple[np.ndarray, np.ndarray]:
    if not is_real(range_max_m):
        raise ValueError(f"{what}: range_max_m must be a number, got {type(range_max_m).__name__} {range_max_m!r:.40}")
    r = frozen_array(ranges, np.float64).reshape(-1)  # the scan's own: a reused buffer cannot change it
    a = frozen_array(angles, np.float64).reshape(-1)
    if r.shape != a.shape:
        raise ValueError(f"{what}: ranges {r.shape} and angles {a.shape} differ in length")
    if not np.all(np.isfinite(r)):
        raise ValueError(f"{what}: ranges contain NaN or inf at beams {np.flatnonzero(~np.isfinite(r))[:10].tolist()}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{what}: angles contain NaN or inf")
    if np.any(r < 0):
        raise ValueError(f"{what}: negative ranges at beams {np.flatnonzero(r < 0)[:10].tolist()}")
    if not (np.isfinite(range_max_m) and range_max_m > 0):
        raise ValueError(f"{what}: range_max_m must be positive, got {range_max_m!r}")
    r.setflags(write=False)
    a.setflags(write=False)
    return r, a


@dataclass(frozen=True, eq=False)
class LaserScan:
    """A lidar scan.

    Attributes:
        ranges: ``(B,)`` finite metres >= 0; ``>= range_max_m`` means no return,
            ``< range_min_m`` invalid.
        angles: ``(B,)`` beam angles in the sensor frame, radians.
        range_max_m: the sensor's maximum range in metres (> 0).
        range_min_m: readings below this are invalid (metres, ``0 <= range_min_m < range_max_m``).
        sensor_pose: ``(3,)`` pose of the sensor in the robot frame ``(x m, y m, theta rad)``.
    """

    ranges: np.ndarray
    angles: np.ndarray
    range_max_m: float
    range_min_m: float = 0.0
    sensor_pose: np.ndarray = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        r, a = _checked_beams(self.ranges, self.angles, self.range_max_m, "LaserScan")
        rmin = self.range_min_m
        if not (is_real(rmin) and math.isfinite(rmin) and 0 <= rmin < self.range_max_m):
            raise ValueError(f"LaserScan: range_min_m must be in [0, range_max_m), got {rmin!r}")
        object.__setattr__(self, "ranges", r)
        object.__setattr__(self, "angles", a)
        object.__setattr__(self, "range_max_m", float(self.range_max_m))
        object.__setattr__(self, "range_min_m", float(rmin))
        object.__setattr__(self, "sensor_pose", _checked_sensor_pose(self.sensor_pose, "LaserScan"))

    @classmethod
    def from_simulator(cls, ranges: np.ndarray, angles: np.ndarray, range_max_m: float) -> LaserScan:
        """A scan of a simulated sensor at the robot centre, without the checks and copies of the
        constructor (an env builds one per step): the same scan as ``LaserScan(ranges, angles, range_max_m)``.

        The caller guarantees what the constructor would check and hands its arrays over: ``ranges``
        a fresh ``(B,)`` float64 array of finite ranges ``>= 0`` that nothing else holds (made read-only
        here), ``angles`` a read-only ``(B,)`` float64 array of finite angles (a sensor's own, shared
        by its scans), ``range_max_m`` a positive float.
        """
        scan = object.__new__(cls)
        _handed_over(scan, ranges=ranges, angles=angles, range_max_m=float(range_max_m), range_min_m=0.0,
                     sensor_pose=_AT_ROBOT_CENTRE)  # fmt: skip
        return scan

    @classmethod
    def from_ros(
        cls,
        ranges,
        angle_min: float,
        angle_increment: float,
        range_min: float,
        range_max: float,
        sensor_pose=(0.0, 0.0, 0.0),
    ) -> LaserScan:
        """A scan from the fields of a ROS ``sensor_msgs/LaserScan`` (REP 117 readings).

        Beam ``i`` is at ``angle_min + i * angle_increment``. Readings are taken as ROS
        defines them:

        * ``+inf`` (nothing within ``range_max``) and finite values ``> range_max``: no
          return, stored as ``range_max`` (skipped by the measurement models, cleared up to
          the limit by mapping). A reading of exactly ``range_max``, valid to REP 117, is then no
          return as well: ``range_max`` is how a `LaserScan` stores one (and how many drivers
          report one);
        * ``NaN`` (erroneous), ``-inf`` (too close to measure) and values ``< range_min``:
          invalid, *dropped* (the scan keeps only the other beams with their own angles,
          so it may have fewer beams than the message).

        Args:
            ranges: the message's ``ranges`` (metres).
            angle_min: angle of the first beam (rad).
            angle_increment: angle between beams (rad; non-zero, may be negative).
            range_min: shortest valid range (m), ``0 <= range_min < range_max``.
            range_max: longest valid range (m).
            sensor_pose: the laser frame's pose in the robot (``base_link``) frame, ``(x, y, yaw)``.
        """
        r = np.asarray(ranges, dtype=np.float64)
        if r.ndim != 1:
            raise ValueError(f"LaserScan.from_ros: ranges must be 1-D (one reading per beam), got shape {r.shape}")
        for name, v in (("angle_min", angle_min), ("angle_increment", angle_increment), ("range_min", range_min),
                        ("range_max", range_max)):  # fmt: skip
            if not is_real(v):
                raise ValueError(f"LaserScan.from_ros: {name} must be a number, got {type(v).__name__} {v!r:.40}")
            if not math.isfinite(v) and name.startswith("angle"):
                raise ValueError(f"LaserScan.from_ros: {name} must be finite, got {v!r}")
        if angle_increment == 0:
            raise ValueError("LaserScan.from_ros: angle_increment must be non-zero")
        if not (math.isfinite(range_max) and range_max > 0):
            raise ValueError(f"LaserScan.from_ros: range_max must be a positive number, got {range_max!r}")
        if not (math.isfinite(range_min) and 0 <= range_min < range_max):
            raise ValueError(f"LaserScan.from_ros: range_min must be in [0, range_max), got {range_min!r}")
        angles = angle_min + angle_increment * np.arange(r.size)
        keep = ~np.isnan(r) & (r >= range_min)  # NaN, -inf and too-short readings are invalid
        out = np.minimum(r[keep], range_max)  # +inf and beyond-range readings: no return
        return cls(out, angles[keep], float(range_max), float(range_min), sensor_pose)

    @property
    def valid(self) -> np.ndarray:
        """Bool ``(B,)``: beams that hit something within ``[range_min_m, range_max_m)``."""
        return (self.ranges < self.range_max_m) & (self.ranges >= self.range_min_m)

    def endpoints(self) -> tuple[np.ndarray, np.ndarray]:
        """Robot-frame end points ``(x (B,), y (B,))`` of all beams, metres (see `beam_endpoints`)."""
        return beam_endpoints(self.ranges, self.angles, self.sensor_pose)


@dataclass(frozen=True, eq=False)
class SemanticScan:
    """A semantic pseudo-laser scan (paper 004 §2): ranges with a class label per beam.

    Attributes:
        ranges: ``(B,)`` metres to the nearest surface; ``>= range_max_m`` means no return.
        angles: ``(B,)`` beam angles in the *sensor* frame, radians (as for `LaserScan`).
        labels: ``(B,)`` int; ``0`` = no detected object, ``k + 1`` = class ``k`` of the map.
        range_max_m: the camera's maximum range in metres.
        sensor_pose: ``(3,)`` pose of the camera in the robot frame (angles are in its frame).
    """

    ranges: np.ndarray
    angles: np.ndarray
    labels: np.ndarray
    range_max_m: float
    sensor_pose: np.ndarray = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        r, a = _checked_beams(self.ranges, self.angles, self.range_max_m, "SemanticScan")
        lab = np.asarray(self.labels)
        if lab.shape != r.shape:
            raise ValueError(f"SemanticScan: labels {lab.shape} and ranges {r.shape} differ")
        if lab.size and not (is_int_dtype(lab.dtype) or lab.dtype == np.bool_):
            if not np.issubdtype(lab.dtype, np.floating):
                raise ValueError(f"SemanticScan: labels must be class indices (integers), got dtype {lab.dtype}")
            v = lab.astype(np.float64).reshape(-1)
            bad = ~np.isfinite(v) | (v != np.round(v)) | (np.abs(v) > 2.0**62)  # int64 holds them exactly
            if bad.any():
                raise ValueError(
                    f"SemanticScan: labels must be class indices (whole numbers below 2**62), got {float(v[bad][0])!r}"
                )
        lab = lab.astype(np.int64)
        if lab.size and lab.min() < 0:
            raise ValueError("SemanticScan: labels must be >= 0")
        lab.setflags(write=False)
        object.__setattr__(self, "ranges", r)
        object.__setattr__(self, "angles", a)
        object.__setattr__(self, "labels", lab)
        object.__setattr__(self, "range_max_m", float(self.range_max_m))
        object.__setattr__(self, "sensor_pose", _checked_sensor_pose(self.sensor_pose, "SemanticScan"))

    @classmethod
    def from_simulator(
        cls, ranges: np.ndarray, angles: np.ndarray, labels: np.ndarray, range_max_m: float
    ) -> SemanticScan:
        """A scan of a simulated camera at the robot centre, without the checks and copies of the
        constructor: the same scan as ``SemanticScan(ranges, angles, labels, range_max_m)``. The caller
        guarantees what `LaserScan.from_simulator` asks, and hands over ``labels``, a fresh ``(B,)``
        int64 array of class indices ``>= 0`` (made read-only here).
        """
        scan = object.__new__(cls)
        _handed_over(scan, ranges=ranges, angles=angles, labels=labels, range_max_m=float(range_max_m),
                     sensor_pose=_AT_ROBOT_CENTRE)  # fmt: skip
        return scan

    @property
    def labelled(self) -> np.ndarray:
        """Bool ``(B,)``: beams that carry an object class and hit within range."""
        return (self.labels > 0) & (self.ranges < self.range_max_m)

    def endpoints(self) -> tuple[np.ndarray, np.ndarray]:
        """Robot-frame end points ``(x (B,), y (B,))`` of all beams, metres (see `beam_endpoints`)."""
        return beam_endpoints(self.ranges, self.angles, self.sensor_pose)
