"""Frozen, typed configuration of the simulated robot and its sensors (units in names).

Each reaches an env as a ``gym.make`` keyword argument, as a dict or an instance:
``gym.make("SemReloc-v0", lidar={"n_beams": 90})``. Unknown keys are an error.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import TypeVar

T = TypeVar("T")


def coerce_config(cls: type[T], value, what: str, default: T | None = None) -> T:
    """Build ``cls`` from ``None`` (defaults), a dict of overrides, or an instance.

    Args:
        default: the instance ``None`` stands for and a dict overrides (``cls()`` if not given).

    Raises:
        ValueError: unknown keys (the message lists the valid ones) or a wrong type.
    """
    base = default if default is not None else cls()
    if value is None:
        return base
    if isinstance(value, cls):
        return value
    if isinstance(value, dict):
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = set(value) - names
        if unknown:
            raise ValueError(f"{what}: unknown keys {sorted(unknown)}; valid keys: {sorted(names)}")
        try:
            return dataclasses.replace(base, **value)
        except TypeError as e:
            raise ValueError(f"{what}: {e}") from None
    raise ValueError(f"{what}: expected a dict or {cls.__name__}, got {type(value).__name__}")


def _positive(obj, *names: str) -> None:
    for n in names:
        v = getattr(obj, n)
        if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
            raise ValueError(f"{type(obj).__name__}.{n} must be a positive finite number, got {v!r}")


def _probability(obj, *names: str) -> None:
    for n in names:
        v = getattr(obj, n)
        if not (isinstance(v, (int, float)) and 0.0 <= v <= 1.0):
            raise ValueError(f"{type(obj).__name__}.{n} must be a probability in [0, 1], got {v!r}")


@dataclass(frozen=True)
class RobotParams:
    """The differential-drive robot: a disc with speed limits.

    Attributes:
        radius_m: disc radius.
        max_linear_mps: speed at action ``v = 1`` (and of the discrete "forward").
        max_angular_rps: turn rate at action ``omega = 1`` (and of the discrete turns), rad/s.
    """

    radius_m: float = 0.2
    max_linear_mps: float = 0.5
    max_angular_rps: float = 1.0

    def __post_init__(self) -> None:
        _positive(self, "radius_m", "max_linear_mps", "max_angular_rps")


@dataclass(frozen=True)
class PhysicsParams:
    """Control rate and pymunk substeps per control step."""

    control_hz: float = 10.0
    substeps: int = 5

    def __post_init__(self) -> None:
        _positive(self, "control_hz", "substeps")
        if int(self.substeps) != self.substeps:
            raise ValueError("PhysicsParams.substeps must be an integer")

    @property
    def dt_s(self) -> float:
        """Seconds per control step."""
        return 1.0 / self.control_hz


@dataclass(frozen=True)
class LidarParams:
    """A planar lidar at the robot centre.

    Attributes:
        n_beams: beams, evenly spaced over the field of view.
        fov_rad: field of view, centred on the heading (``2*pi``: all around).
        range_max_m: maximum range; no return reads as this value.
        noise_std_m: Gaussian range noise.
        dropout_prob: chance that a beam returns nothing (reads ``range_max_m``).
    """

    n_beams: int = 60
    fov_rad: float = 2 * math.pi
    range_max_m: float = 8.0
    noise_std_m: float = 0.02
    dropout_prob: float = 0.01

    def __post_init__(self) -> None:
        _positive(self, "n_beams", "fov_rad", "range_max_m")
        if self.noise_std_m < 0:
            raise ValueError("LidarParams.noise_std_m must be >= 0")
        _probability(self, "dropout_prob")


@dataclass(frozen=True)
class CameraParams:
    """The semantic pseudo-laser (paper 004 §2): a depth camera plus an object detector.

    Attributes:
        n_beams: image columns kept as beams, evenly spaced over the field of view.
        fov_rad: horizontal field of view (default 70 deg), centred on the heading.
        range_min_m, range_max_m: depth range; beams outside read ``range_max_m`` (no return).
        noise_std_m: Gaussian depth noise.
        miss_rate: chance that a visible object is not detected in a frame.
        wrong_class_rate: chance that a detection carries a wrong (uniformly drawn other) class.
        false_positive_rate: chance per frame of one spurious detection on a wall run.
    """

    n_beams: int = 32
    fov_rad: float = math.radians(70.0)
    range_min_m: float = 0.5
    range_max_m: float = 4.5
    noise_std_m: float = 0.02
    miss_rate: float = 0.1
    wrong_class_rate: float = 0.05
    false_positive_rate: float = 0.02

    def __post_init__(self) -> None:
        _positive(self, "n_beams", "fov_rad", "range_max_m")
        if not 0 <= self.range_min_m < self.range_max_m:
            raise ValueError("CameraParams needs 0 <= range_min_m < range_max_m")
        if self.noise_std_m < 0:
            raise ValueError("CameraParams.noise_std_m must be >= 0")
        _probability(self, "miss_rate", "wrong_class_rate", "false_positive_rate")


def default_odometry_noise():
    """The simulator's odometry noise: the filters' model with small alphas (a good wheel encoder)."""
    from filters.motion.odometry import OdometryMotionConfig

    return OdometryMotionConfig(alpha1=0.02, alpha2=0.02, alpha3=0.02, alpha4=0.01)
