"""Pose helpers shared by every filter: angle wrapping and frame composition.

A pose is ``(x, y, theta)`` in metres and radians, theta wrapped to ``[-pi, pi)``.
Arrays of poses have shape ``(N, 3)``.
"""

from __future__ import annotations

import math

import numba
import numpy as np


def wrap_angle(a):
    """Wrap angles (scalar or array, radians) to ``[-pi, pi)``; an angle within rounding below ``-pi`` (such as
    ``nextafter(-pi, -inf)``) comes out as ``+pi`` itself, the same angle (the compiled kernels use the same
    formula, and the episodes' bits depend on it)."""
    return (np.asarray(a) + np.pi) % (2.0 * np.pi) - np.pi


@numba.njit(cache=True, nogil=True)
def _cos_sin(theta, c, s):  # pragma: no cover - compiled
    for i in range(theta.shape[0]):
        c[i] = math.cos(theta[i])  # LLVM makes the pair one sincos call
        s[i] = math.sin(theta[i])


def cos_sin(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(np.cos(theta), np.sin(theta))`` of a 1D array of angles (radians, taken as float64) in one compiled pass
    (the C library's ``sincos``, about 1.6x faster than the two NumPy calls). The same bits where NumPy's float64
    ``cos`` and ``sin`` are the C library's, as on the platforms this package is tested on
    (``tests/test_belief_kernels.py`` checks it; the compiled kernels' tests against their NumPy references rely on
    it too). Unlike NumPy it never warns for an infinite angle (the result is NaN all the same).

    Raises:
        ValueError: ``theta`` is not 1D."""
    theta = np.asarray(theta, dtype=np.float64)
    if theta.ndim != 1:
        raise ValueError(f"cos_sin takes a 1D array of angles, got shape {theta.shape}")
    c = np.empty(theta.shape[0])
    s = np.empty(theta.shape[0])
    _cos_sin(theta, c, s)
    return c, s


def wrap_float(a: float) -> float:
    """`wrap_angle` of one Python float, as a Python float, without NumPy's per-call cost: the same bits (Python's
    floored modulo of floats is NumPy's)."""
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def finite_increment(delta, what: str = "delta") -> tuple[float, float, float]:
    """``(dx, dy, dtheta)`` of a robot-frame increment (m, m, rad) as Python floats.

    Raises:
        ValueError: ``delta`` is not 3 finite numbers (the message names it as ``what``)."""
    d = np.asarray(delta, dtype=np.float64).reshape(-1)
    dx, dy, dt = d.tolist() if d.shape == (3,) else (math.nan,) * 3
    if not (math.isfinite(dx) and math.isfinite(dy) and math.isfinite(dt)):
        raise ValueError(f"{what} must be 3 finite numbers (dx m, dy m, dtheta rad), got {delta!r:.80}")
    return dx, dy, dt


def compose_floats(x: float, y: float, theta: float, dx: float, dy: float, dtheta: float) -> tuple[float, float, float]:
    """`compose` of one pose with one increment in Python floats, the same bits as its array path for finite results
    (``cos`` and ``sin`` the C library's, as NumPy's float64 ones: see `cos_sin`); a result may overflow to inf."""
    c, s = math.cos(theta), math.sin(theta)
    return x + c * dx - s * dy, y + s * dx + c * dy, wrap_float(theta + dtheta)


def compose(pose: np.ndarray, delta: np.ndarray, trig: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """Apply the robot-frame increment ``delta = (dx, dy, dtheta)`` to ``pose``.

    Both may be ``(3,)`` or ``(N, 3)``; broadcasting applies. Returns wrapped poses. ``trig``:
    ``(np.cos(pose[..., 2]), np.sin(pose[..., 2]))`` if the caller has them already (None: computed here).
    """
    pose = np.asarray(pose, dtype=np.float64)
    delta = np.asarray(delta, dtype=np.float64)
    if trig is None and pose.shape == (3,) and delta.shape == (3,):
        x0, y0, t0 = pose.tolist()
        dx, dy, dt = delta.tolist()
        if math.isfinite(x0 + y0 + t0 + dx + dy + dt):  # one pose, finite: the same arithmetic in Python floats
            x, y, th = compose_floats(x0, y0, t0, dx, dy, dt)
            if math.isfinite(x + y + th):  # else an overflow: the array path below, with NumPy's warnings
                return np.array([x, y, th])
    c, s = trig if trig is not None else (np.cos(pose[..., 2]), np.sin(pose[..., 2]))
    x = pose[..., 0] + c * delta[..., 0] - s * delta[..., 1]
    y = pose[..., 1] + s * delta[..., 0] + c * delta[..., 1]
    th = wrap_angle(pose[..., 2] + delta[..., 2])
    return np.stack([x, y, th], axis=-1)


def relative_floats(pose_from, pose_to) -> tuple[float, float, float]:
    """`relative` of two ``(3,)`` poses as three Python floats, without NumPy's per-call cost: the same numbers."""
    ax, ay, ath = np.asarray(pose_from, dtype=np.float64).tolist()
    bx, by, bth = np.asarray(pose_to, dtype=np.float64).tolist()
    dx, dy = bx - ax, by - ay
    c, s = math.cos(ath), math.sin(ath)  # the C library's, as NumPy's float64 cos and sin (see cos_sin)
    return c * dx + s * dy, -s * dx + c * dy, wrap_float(bth - ath)


def relative(pose_from: np.ndarray, pose_to: np.ndarray) -> np.ndarray:
    """The robot-frame increment that takes ``pose_from`` to ``pose_to`` (inverse of compose)."""
    a = np.asarray(pose_from, dtype=np.float64)
    b = np.asarray(pose_to, dtype=np.float64)
    dx, dy = b[..., 0] - a[..., 0], b[..., 1] - a[..., 1]
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    return np.stack([c * dx + s * dy, -s * dx + c * dy, wrap_angle(b[..., 2] - a[..., 2])], axis=-1)
