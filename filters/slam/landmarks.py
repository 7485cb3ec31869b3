"""Range-bearing observation model for 2D point landmarks.

A pose is ``(x, y, theta)`` (m, m, rad); a landmark is ``(x, y)`` (m); an
observation is ``z = (r, b)``: range ``r >= 0`` in metres and bearing ``b`` in
radians relative to the robot heading, wrapped to ``[-pi, pi)`` (paper 000 Eq. 3)::

    r = sqrt((lx - x)^2 + (ly - y)^2),   b = atan2(ly - y, lx - x) - theta

Every function broadcasts over leading axes, so ``poses[:, None, :]`` against
``landmarks`` of shape ``(N, M, 2)`` predicts all ``N x M`` observations at once.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from filters.numbers import MAX_LENGTH_M, is_int_dtype, is_real
from filters.pose import wrap_angle

MIN_NOISE_SIGMA = 1e-9
"""Smallest observation noise standard deviation taken (m or rad): the filters divide by ``det(R)``, which
underflowed to 0 with both at 1e-100 and gave NaN landmarks."""


@dataclass(frozen=True)
class RangeBearingNoise:
    """Standard deviations of additive Gaussian observation noise: range (m) and bearing (rad)."""

    sigma_r_m: float
    sigma_b_rad: float

    def __post_init__(self) -> None:
        lo = MIN_NOISE_SIGMA
        if not (lo <= self.sigma_r_m <= MAX_LENGTH_M and lo <= self.sigma_b_rad <= 2 * math.pi):
            raise ValueError(
                f"observation noise: sigma_r_m must be in [{lo:g}, {MAX_LENGTH_M:g}] m and sigma_b_rad in "
                f"[{lo:g}, 2 pi] rad, got {self}"
            )

    @property
    def cov(self) -> np.ndarray:
        """Observation covariance ``R = diag(sigma_r^2, sigma_b^2)``, shape ``(2, 2)``."""
        return np.diag([self.sigma_r_m**2, self.sigma_b_rad**2])


def predict_observation(poses: np.ndarray, landmarks: np.ndarray) -> np.ndarray:
    """Noise-free ``(r, b)`` of ``landmarks (..., 2)`` seen from ``poses (..., 3)``; shape ``(..., 2)``."""
    poses = np.asarray(poses, dtype=np.float64)
    landmarks = np.asarray(landmarks, dtype=np.float64)
    dx = landmarks[..., 0] - poses[..., 0]
    dy = landmarks[..., 1] - poses[..., 1]
    r = np.hypot(dx, dy)
    b = wrap_angle(np.arctan2(dy, dx) - poses[..., 2])
    return np.stack([r, b], axis=-1)


def observation_jacobians(poses: np.ndarray, landmarks: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Predicted observation and its Jacobians wrt pose and landmark.

    Returns ``(z_hat (..., 2), H_pose (..., 2, 3), H_landmark (..., 2, 2))``. The
    range must be positive (a landmark exactly at the robot has no bearing); a
    floor of 1e-9 m keeps the arrays finite in that degenerate case.
    """
    poses = np.asarray(poses, dtype=np.float64)
    landmarks = np.asarray(landmarks, dtype=np.float64)
    dx = landmarks[..., 0] - poses[..., 0]
    dy = landmarks[..., 1] - poses[..., 1]
    q = np.maximum(dx * dx + dy * dy, 1e-18)
    r = np.sqrt(q)
    z = np.stack([r, wrap_angle(np.arctan2(dy, dx) - poses[..., 2])], axis=-1)
    shape = dx.shape
    h_l = np.empty(shape + (2, 2))
    h_l[..., 0, 0] = dx / r
    h_l[..., 0, 1] = dy / r
    h_l[..., 1, 0] = -dy / q
    h_l[..., 1, 1] = dx / q
    h_x = np.empty(shape + (2, 3))
    h_x[..., :, :2] = -h_l
    h_x[..., 0, 2] = 0.0
    h_x[..., 1, 2] = -1.0
    return z, h_x, h_l


def inverse_observation(poses: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Landmark position that would produce ``z (..., 2)`` from ``poses (..., 3)``.

    Returns ``(landmarks (..., 2), G_pose (..., 2, 3), G_z (..., 2, 2))`` -- the
    Jacobians of the landmark position wrt pose and observation, used to
    initialise a new landmark's covariance ``G_z R G_z^T (+ G_pose P G_pose^T)``.
    """
    poses = np.asarray(poses, dtype=np.float64)
    z = np.asarray(z, dtype=np.float64)
    r, b = z[..., 0], z[..., 1]
    a = poses[..., 2] + b
    c, s = np.cos(a), np.sin(a)
    lm = np.stack([poses[..., 0] + r * c, poses[..., 1] + r * s], axis=-1)
    shape = np.broadcast_shapes(poses.shape[:-1], z.shape[:-1])
    g_z = np.empty(shape + (2, 2))
    g_z[..., 0, 0] = c
    g_z[..., 0, 1] = -r * s
    g_z[..., 1, 0] = s
    g_z[..., 1, 1] = r * c
    g_x = np.zeros(shape + (2, 3))
    g_x[..., 0, 0] = 1.0
    g_x[..., 1, 1] = 1.0
    g_x[..., 0, 2] = -r * s
    g_x[..., 1, 2] = r * c
    return np.broadcast_to(lm, shape + (2,)).copy(), g_x, g_z


MAX_RANGE_M = MAX_LENGTH_M
"""Largest observation range `validate_observations` accepts (m): no range-bearing sensor measures farther,
and the squares of far larger ranges overflow the filters' covariance arithmetic (inf landmark covariances)."""


def validate_observations(z, ids=None) -> tuple[np.ndarray, np.ndarray | None]:
    """Check one scan of range-bearing observations and return it as arrays.

    ``z`` is ``(K, 2)`` (``K = 0`` allowed; ``None`` means no observation), rows
    ``(r, b)``. ``ids``, if given, is ``K`` non-negative integer landmark ids.
    Returns ``(z float64 (K, 2) with bearings wrapped to [-pi, pi), ids int64 (K,) or None)``.

    Raises ValueError for values that are not real numbers (bools, complex numbers, strings), a wrong shape,
    NaN/inf, a negative range or one above `MAX_RANGE_M`, a bearing outside ``[-pi, pi]``, or ids of the wrong
    length / negative / non-integer. Ids may repeat: the filters apply each observation to its landmark in turn.
    """
    if z is None:
        z = np.zeros((0, 2))
    z = np.asarray(z)
    if z.size and z.dtype.kind not in "iuf":  # no bools, complex numbers, strings or objects
        raise ValueError(f"observations must be real numbers (range_m, bearing_rad), got dtype {z.dtype}")
    z = z.astype(np.float64)
    if z.size == 0:
        z = z.reshape(0, 2)
    if z.ndim != 2 or z.shape[1] != 2:
        raise ValueError(f"observations must have shape (K, 2) rows (range_m, bearing_rad), got {z.shape}")
    if not np.all(np.isfinite(z)):
        raise ValueError("observations contain NaN or inf")
    if np.any(z[:, 0] < 0):
        raise ValueError(f"observation ranges must be >= 0 m, got min {z[:, 0].min():.6g}")
    if np.any(z[:, 0] > MAX_RANGE_M):
        raise ValueError(f"observation ranges must be at most {MAX_RANGE_M:g} m, got max {z[:, 0].max():.6g}")
    if np.any(np.abs(z[:, 1]) > np.pi):
        raise ValueError(f"observation bearings must lie in [-pi, pi] rad, got max |b| = {np.abs(z[:, 1]).max():.6g}")
    z = z.copy()
    z[:, 1] = wrap_angle(z[:, 1])
    if ids is None:
        return z, None
    ids_arr = np.asarray(ids)
    if ids_arr.size == 0:
        ids_arr = ids_arr.reshape(0)
    if ids_arr.ndim != 1 or ids_arr.shape[0] != z.shape[0]:
        raise ValueError(f"ids must have shape ({z.shape[0]},), got {ids_arr.shape}")
    if ids_arr.size and (not is_int_dtype(ids_arr.dtype) or np.any(ids_arr < 0)):
        raise ValueError("landmark ids must be non-negative integers")
    return z, ids_arr.astype(np.int64)


def checked_control(u, dt) -> tuple[np.ndarray, float]:
    """``(u as a finite float64 1-D array, dt as a float)``; ValueError unless ``dt`` is a finite
    number > 0 and ``u`` finite numbers (the SLAM filters' ``predict`` checks with this before they
    move anything; the motion model fixes how many, e.g. ``(v, omega)`` or ``(dx, dy, dtheta)``)."""
    if not (is_real(dt) and math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be a finite number > 0 (seconds), got {dt!r}")
    try:
        a = np.asarray(u, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"control u must be numbers, got {u!r:.80}") from None
    if a.ndim != 1 or a.size == 0 or not np.all(np.isfinite(a)):
        raise ValueError(f"control u must be a 1-D array of finite numbers, got {u!r:.80}")
    return a, float(dt)


def check_finite_motion(u: np.ndarray, dt: float, what: str, *results: np.ndarray) -> None:
    """ValueError unless every array of ``results`` (what ``predict`` computed from the checked control
    ``u`` over ``dt``) is finite; ``what`` names the moved state ("pose", "poses") in the message."""
    if not all(np.all(np.isfinite(r)) for r in results):
        raise ValueError(f"control u={u.tolist()} over dt={dt} s moves the {what} off any finite value")


def checked_pose_cov(cov, what: str = "initial_pose_cov") -> np.ndarray:
    """``cov`` as a ``(3, 3)`` float64 covariance: finite, symmetric (to 1e-9 relative) and positive
    semi-definite; ValueError naming ``what`` otherwise."""
    p = np.array(cov, dtype=np.float64)
    if p.shape != (3, 3):
        raise ValueError(f"{what} must be (3, 3), got shape {p.shape}")
    if not np.all(np.isfinite(p)):
        raise ValueError(f"{what} must be finite, got {p.tolist()}")
    if not np.allclose(p, p.T, rtol=1e-9, atol=1e-12):
        raise ValueError(f"{what} must be symmetric, got {p.tolist()}")
    if np.linalg.eigvalsh(p).min() < -1e-12 * max(1.0, float(np.abs(p).max())):
        raise ValueError(f"{what} must be positive semi-definite, got {p.tolist()}")
    return p
