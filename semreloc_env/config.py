"""Frozen, typed configuration of the simulated robot and its sensors (units in names).

Each reaches an env as a ``gym.make`` keyword argument, as a dict or an instance:
``gym.make("SemReloc-v1", lidar={"n_beams": 90})``. Unknown keys are an error, and types
are strict (`coerce_config`): ``True`` is not an int, ``1.5`` or ``2.0`` is not an int,
``"no"`` is not a bool, NaN and infinite floats are rejected.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import types
import typing
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TypeVar

import numpy as np

from filters.numbers import is_int, is_real

T = TypeVar("T")

MAX_SUBSTEPS = 1000
"""Most pymunk substeps per control step (each costs a collision query)."""

MAX_BEAMS = 10_000
"""Most beams of a lidar or a camera."""

MAX_RANGE_M = 10_000.0
"""Largest sensor range accepted (m): beyond it the observation bounds stop being meaningful."""

MAX_REWARD_WEIGHT = 1e6
"""Largest magnitude of a reward weight: larger ones can make a reward (a sum of weighted terms) infinite."""


def check_reward_weights(obj) -> None:
    """ValueError unless every field of the dataclass ``obj`` is a finite real within ``+-MAX_REWARD_WEIGHT``."""
    for f in dataclasses.fields(obj):
        v = getattr(obj, f.name)
        if not (is_real(v) and math.isfinite(v) and abs(v) <= MAX_REWARD_WEIGHT):
            raise ValueError(
                f"reward weight {f.name} must be a finite number within +-{MAX_REWARD_WEIGHT:g}, got {v!r}"
            )
        object.__setattr__(obj, f.name, float(v))


def _key_list(keys) -> list:
    """Keys sorted for a message even when they are of mixed types (``{"a", 7}``)."""
    return sorted(keys, key=repr)


@functools.cache
def _hints(cls: type) -> dict:
    try:
        return typing.get_type_hints(cls)
    except Exception:  # an annotation that cannot be resolved is not checked
        return {}


@functools.cache
def _inf_ok(cls: type, name: str) -> bool:
    """Infinity is a valid value of field ``name``: listed in ``cls._allow_inf``, or its default is infinite."""
    if name in getattr(cls, "_allow_inf", ()):
        return True
    default = next((f.default for f in dataclasses.fields(cls) if f.name == name), None)
    return isinstance(default, float) and math.isinf(default)


def _type_name(v) -> str:
    return f"{type(v).__name__} {v!r:.60}"


def _check_value(cls: type, name: str, v, ann, what: str):
    """``v`` checked against annotation ``ann`` (and converted: numpy scalars to Python ones).

    A bool is not an int, an int or float is not a bool, a string is not a number; floats must be
    finite unless ``name`` is in ``cls._allow_inf`` or its default is infinite; NaN never passes.
    """
    where = f"{what}.{name}"
    origin = typing.get_origin(ann)
    if origin in (typing.Union, types.UnionType):
        members = typing.get_args(ann)
        if v is None and type(None) in members:
            return None
        errors = []
        for m in members:
            if m is type(None):
                continue
            try:
                return _check_value(cls, name, v, m, what)
            except ValueError as e:
                errors.append(str(e))
        raise ValueError(f"{where} must be one of {ann}, got {_type_name(v)}")
    if ann is bool:
        if isinstance(v, (bool, np.bool_)):
            return bool(v)
        raise ValueError(f"{where} must be a bool (True or False), got {_type_name(v)}")
    if ann is int:
        if is_int(v):
            return int(v)
        raise ValueError(f"{where} must be an integer, got {_type_name(v)}")
    if ann is float:
        if not is_real(v):
            raise ValueError(f"{where} must be a number, got {_type_name(v)}")
        f = float(v)
        if math.isnan(f) or (math.isinf(f) and not _inf_ok(cls, name)):
            raise ValueError(f"{where} must be a finite number, got {f!r}")
        return f
    if ann is str:
        if isinstance(v, str):
            return v
        raise ValueError(f"{where} must be a string, got {_type_name(v)}")
    if ann is dict:
        if isinstance(v, Mapping):
            return v
        raise ValueError(f"{where} must be a dict, got {_type_name(v)}")
    if origin is tuple:
        if isinstance(v, np.ndarray) and v.ndim == 1:
            v = v.tolist()  # a 1-D array is a sequence of numbers, as a list is
        if not isinstance(v, (tuple, list)):
            raise ValueError(f"{where} must be a tuple or list, got {_type_name(v)}")
        args = typing.get_args(ann)
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_check_value(cls, f"{name}[{i}]", x, args[0], what) for i, x in enumerate(v))
        return tuple(v)
    if isinstance(ann, type) and dataclasses.is_dataclass(ann):
        if isinstance(v, ann):
            check_config(v, where)
            return v
        raise ValueError(f"{where} must be a {ann.__name__} or a dict of its fields, got {_type_name(v)}")
    return v  # annotations this checker does not know are left to the class


def check_config(obj, what: str | None = None) -> None:
    """Check every field of a config dataclass instance against its annotation (see `coerce_config`).

    Raises:
        ValueError: naming the field, for a value of the wrong type or a NaN / infinite float.
    """
    cls = type(obj)
    what = what or cls.__name__
    hints = _hints(cls)
    for f in dataclasses.fields(obj):
        if f.name in hints:
            _check_value(cls, f.name, getattr(obj, f.name), hints[f.name], what)


def coerce_config(cls: type[T], value, what: str, default: T | None = None) -> T:
    """Build ``cls`` from ``None`` (defaults), a dict of overrides, or an instance, with strict types.

    A dict overrides the fields it names and keeps the others from ``default``; a dict given
    for a field that is itself a config dataclass is merged the same way into that field's
    value in ``default`` (``{"semantic_field": {"sigma_hit_m": 0.4}}`` keeps the semantic
    field's other defaults). Types follow the annotations: a bool is not an int, a float
    (even ``2.0``) is not an int, a string is not a bool or a number, NaN and infinite
    floats are rejected (infinity is kept where the field's default is infinite or the
    class lists the field in ``_allow_inf``). Instances
    are checked the same way.

    Args:
        default: the instance ``None`` stands for and a dict overrides (``cls()`` if not given).

    Raises:
        ValueError: unknown keys (the message lists the valid ones), a wrong type or an
            invalid value; the message names the argument and the field.
    """
    if value is None:
        out = default if default is not None else cls()
    elif isinstance(value, cls):
        out = value
    elif isinstance(value, Mapping):
        out = _merge(cls, default if default is not None else cls(), value, what)
    else:
        raise ValueError(f"{what}: expected a dict or {cls.__name__}, got {type(value).__name__}")
    check_config(out, what)
    return out


def _merge(cls: type[T], base: T, value: Mapping, what: str) -> T:
    names = {f.name for f in dataclasses.fields(cls)}
    unknown = set(value) - names
    if unknown:
        raise ValueError(f"{what}: unknown keys {_key_list(unknown)}; valid keys: {sorted(names)}")
    hints = _hints(cls)
    changes = {}
    for k, v in value.items():
        ann = hints.get(k)
        if isinstance(ann, type) and dataclasses.is_dataclass(ann) and isinstance(v, Mapping):
            current = getattr(base, k)
            changes[k] = coerce_config(ann, v, f"{what}.{k}", current if isinstance(current, ann) else None)
        elif ann is not None:
            changes[k] = _check_value(cls, k, v, ann, what)
        else:
            changes[k] = v
    try:
        return dataclasses.replace(base, **changes)
    except (TypeError, ValueError) as e:
        raise ValueError(f"{what}: {e}") from None


def _positive(obj, *names: str) -> None:
    for n in names:
        v = getattr(obj, n)
        if not (isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and v > 0):
            raise ValueError(f"{type(obj).__name__}.{n} must be a positive finite number, got {v!r}")


def _at_most(obj, name: str, hi: float) -> None:
    v = getattr(obj, name)
    if v > hi:
        raise ValueError(f"{type(obj).__name__}.{name} must be at most {hi:g}, got {v!r}")


def _non_negative(obj, *names: str) -> None:
    for n in names:
        v = getattr(obj, n)
        if not (isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and v >= 0):
            raise ValueError(f"{type(obj).__name__}.{n} must be a finite number >= 0, got {v!r}")


def _probability(obj, *names: str) -> None:
    for n in names:
        v = getattr(obj, n)
        if not (isinstance(v, (int, float)) and not isinstance(v, bool) and 0.0 <= v <= 1.0):
            raise ValueError(f"{type(obj).__name__}.{n} must be a probability in [0, 1], got {v!r}")


def _int_range(obj, name: str, lo: int, hi: int) -> None:
    v = getattr(obj, name)
    if not (is_int(v) and lo <= v <= hi):
        raise ValueError(f"{type(obj).__name__}.{name} must be an integer in [{lo}, {hi}], got {v!r}")


def _fov(obj) -> None:
    _positive(obj, "fov_rad")
    if obj.fov_rad > 2 * math.pi + 1e-9:
        raise ValueError(f"{type(obj).__name__}.fov_rad must be in (0, 2*pi], got {obj.fov_rad!r}")


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
        check_config(self)
        _positive(self, "radius_m", "max_linear_mps", "max_angular_rps")


@dataclass(frozen=True)
class PhysicsParams:
    """Control rate (Hz) and pymunk substeps per control step (an integer in ``[1, MAX_SUBSTEPS]``)."""

    control_hz: float = 10.0
    substeps: int = 5

    def __post_init__(self) -> None:
        check_config(self)
        _positive(self, "control_hz")
        _int_range(self, "substeps", 1, MAX_SUBSTEPS)

    @property
    def dt_s(self) -> float:
        """Seconds per control step."""
        return 1.0 / self.control_hz


@dataclass(frozen=True)
class LidarParams:
    """A planar lidar at the robot centre.

    Attributes:
        n_beams: beams, evenly spaced over the field of view (an integer in ``[1, MAX_BEAMS]``).
        fov_rad: field of view, centred on the heading, in ``(0, 2*pi]`` (``2*pi``: all around).
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
        check_config(self)
        _int_range(self, "n_beams", 1, MAX_BEAMS)
        _fov(self)
        _positive(self, "range_max_m")
        _at_most(self, "range_max_m", MAX_RANGE_M)
        _non_negative(self, "noise_std_m")
        _probability(self, "dropout_prob")


@dataclass(frozen=True)
class CameraParams:
    """The semantic pseudo-laser (paper 004 §2): a depth camera plus an object detector.

    Attributes:
        n_beams: image columns kept as beams, evenly spaced over the field of view (``[1, MAX_BEAMS]``).
        fov_rad: horizontal field of view (default 70 deg), centred on the heading, in ``(0, 2*pi]``.
            With ``2*pi`` the first and last beams are neighbours, but the detector does not join runs
            across that seam: an object straight behind the robot, hit by beams at both ends of the
            array, carries its class on one end's run only (the other reads class 0, as a wall does).
        range_min_m, range_max_m: depth range; beams outside read ``range_max_m`` (no return). A beam on
            an object within range whose noisy depth reaches ``range_max_m`` is clipped there and keeps
            its class (the filters ignore beams at ``range_max_m``).
        noise_std_m: Gaussian depth noise.
        miss_rate: chance that a visible object is not detected in a frame.
        wrong_class_rate: chance that a detection carries a wrong (uniformly drawn other) class.
        false_positive_rate: chance per frame of one spurious detection: the first 1-4 beams of a
            randomly drawn run of wall beams get a random class.
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
        check_config(self)
        _int_range(self, "n_beams", 1, MAX_BEAMS)
        _fov(self)
        _positive(self, "range_max_m")
        _at_most(self, "range_max_m", MAX_RANGE_M)
        _non_negative(self, "range_min_m", "noise_std_m")
        if not self.range_min_m < self.range_max_m:
            raise ValueError("CameraParams needs 0 <= range_min_m < range_max_m")
        _probability(self, "miss_rate", "wrong_class_rate", "false_positive_rate")


def default_odometry_noise(exact_small_moves: bool = True):
    """The simulator's odometry noise: the filters' model with small alphas (a good wheel encoder), a step under
    ``min_trans_m`` moved in its own direction if ``exact_small_moves`` (the newest envs' default, ``SemReloc-v22``'s
    and ``SemSlam-v2``'s; False gives the noise of ``SemReloc-v21`` and older and of ``SemSlam-v1`` and ``-v0``). To
    change a few fields of the newest env's noise, pass them as a dict (``odometry={"alpha1": 0.05}``): an
    `OdometryMotionConfig` instance replaces it whole, ``exact_small_moves`` included."""
    from filters.motion.odometry import OdometryMotionConfig

    return OdometryMotionConfig(alpha1=0.02, alpha2=0.02, alpha3=0.02, alpha4=0.01, exact_small_moves=exact_small_moves)
