"""Scan containers: what a range sensor hands to a filter.

Every scan is taken from the robot's centre (the sensor is mounted at the pose
origin), with beam angles in the robot frame, radians, counter-clockwise from
the heading. A beam whose range is ``>= range_max_m`` returned nothing and is
skipped by the measurement models.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def _checked_beams(ranges, angles, range_max_m: float, what: str) -> tuple[np.ndarray, np.ndarray]:
    r = np.asarray(ranges, dtype=np.float64).reshape(-1)
    a = np.asarray(angles, dtype=np.float64).reshape(-1)
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
        ranges: ``(B,)`` metres; ``>= range_max_m`` means no return.
        angles: ``(B,)`` beam angles in the robot frame, radians.
        range_max_m: the sensor's maximum range in metres.
    """

    ranges: np.ndarray
    angles: np.ndarray
    range_max_m: float

    def __post_init__(self) -> None:
        r, a = _checked_beams(self.ranges, self.angles, self.range_max_m, "LaserScan")
        object.__setattr__(self, "ranges", r)
        object.__setattr__(self, "angles", a)
        object.__setattr__(self, "range_max_m", float(self.range_max_m))

    @property
    def valid(self) -> np.ndarray:
        """Bool ``(B,)``: beams that hit something within range."""
        return self.ranges < self.range_max_m


@dataclass(frozen=True, eq=False)
class SemanticScan:
    """A semantic pseudo-laser scan (paper 004 §2): ranges with a class label per beam.

    Attributes:
        ranges: ``(B,)`` metres to the nearest surface; ``>= range_max_m`` means no return.
        angles: ``(B,)`` beam angles in the robot frame, radians.
        labels: ``(B,)`` int; ``0`` = no detected object, ``k + 1`` = class ``k`` of the map.
        range_max_m: the camera's maximum range in metres.
    """

    ranges: np.ndarray
    angles: np.ndarray
    labels: np.ndarray
    range_max_m: float

    def __post_init__(self) -> None:
        r, a = _checked_beams(self.ranges, self.angles, self.range_max_m, "SemanticScan")
        lab = np.asarray(self.labels)
        if lab.shape != r.shape:
            raise ValueError(f"SemanticScan: labels {lab.shape} and ranges {r.shape} differ")
        if lab.size and (not np.issubdtype(lab.dtype, np.integer) and not np.all(lab == np.round(lab))):
            raise ValueError("SemanticScan: labels must be integers")
        lab = lab.astype(np.int64)
        if lab.size and lab.min() < 0:
            raise ValueError("SemanticScan: labels must be >= 0")
        lab.setflags(write=False)
        object.__setattr__(self, "ranges", r)
        object.__setattr__(self, "angles", a)
        object.__setattr__(self, "labels", lab)
        object.__setattr__(self, "range_max_m", float(self.range_max_m))

    @property
    def labelled(self) -> np.ndarray:
        """Bool ``(B,)``: beams that carry an object class and hit within range."""
        return (self.labels > 0) & (self.ranges < self.range_max_m)
