"""Pluggable motion models for landmark SLAM, vectorised over ``(N, 3)`` pose arrays.

Every model offers

* ``mean(poses, u, dt)`` -- noise-free next poses, ``(N, 3)``;
* ``jacobians(poses, u, dt)`` -- ``(F_x (N, 3, 3), F_u (N, 3, 2))`` of ``mean`` wrt pose and control;
* ``sample(poses, u, dt, rng)`` -- next poses with control noise drawn independently per row;
* ``control_cov`` -- the ``(2, 2)`` covariance of the additive control noise.

``u`` is one control ``(2,)`` shared by all rows; ``dt`` is in seconds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from filters.numbers import is_real
from filters.pose import wrap_angle


@runtime_checkable
class MotionModel(Protocol):
    """What the SLAM filters need from a motion model (see the module docstring)."""

    @property
    def control_cov(self) -> np.ndarray: ...

    def mean(self, poses: np.ndarray, u: np.ndarray, dt: float) -> np.ndarray: ...

    def jacobians(self, poses: np.ndarray, u: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]: ...

    def sample(self, poses: np.ndarray, u: np.ndarray, dt: float, rng: np.random.Generator) -> np.ndarray: ...


def _control(u) -> np.ndarray:
    u = np.asarray(u, dtype=np.float64)
    if u.shape != (2,) or not np.all(np.isfinite(u)):
        raise ValueError(f"control must be a finite (2,) array, got {u!r}")
    return u


@dataclass(frozen=True)
class BicycleModel:
    """Car-like model of Bailey's SLAM simulators; control ``u = (v m/s, G steering rad)``::

        x += v dt cos(G + theta);  y += v dt sin(G + theta);  theta += v dt sin(G) / wheelbase

    Control noise: ``v ~ N(v, sigma_v^2)``, ``G ~ N(G, sigma_g^2)``.
    """

    wheelbase_m: float = 4.0
    sigma_v_mps: float = 0.3
    sigma_g_rad: float = float(np.deg2rad(3.0))

    def __post_init__(self) -> None:
        values = (self.wheelbase_m, self.sigma_v_mps, self.sigma_g_rad)
        if not (all(is_real(v) and math.isfinite(v) for v in values) and values[0] > 0 and min(values[1:]) >= 0):
            raise ValueError(f"invalid bicycle model parameters (finite, wheelbase > 0, sigmas >= 0): {self}")

    @property
    def control_cov(self) -> np.ndarray:
        return np.diag([self.sigma_v_mps**2, self.sigma_g_rad**2])

    def _step(self, poses: np.ndarray, v, g, dt: float) -> np.ndarray:
        a = g + poses[:, 2]
        out = np.empty_like(poses)
        out[:, 0] = poses[:, 0] + v * dt * np.cos(a)
        out[:, 1] = poses[:, 1] + v * dt * np.sin(a)
        out[:, 2] = wrap_angle(poses[:, 2] + v * dt * np.sin(g) / self.wheelbase_m)
        return out

    def mean(self, poses, u, dt):
        v, g = _control(u)
        return self._step(np.asarray(poses, dtype=np.float64).reshape(-1, 3), v, g, dt)

    def jacobians(self, poses, u, dt):
        v, g = _control(u)
        poses = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
        n = poses.shape[0]
        a = g + poses[:, 2]
        ca, sa = np.cos(a), np.sin(a)
        fx = np.zeros((n, 3, 3))
        fx[:, 0, 0] = fx[:, 1, 1] = fx[:, 2, 2] = 1.0
        fx[:, 0, 2] = -v * dt * sa
        fx[:, 1, 2] = v * dt * ca
        fu = np.empty((n, 3, 2))
        fu[:, 0, 0] = dt * ca
        fu[:, 0, 1] = -v * dt * sa
        fu[:, 1, 0] = dt * sa
        fu[:, 1, 1] = v * dt * ca
        fu[:, 2, 0] = dt * np.sin(g) / self.wheelbase_m
        fu[:, 2, 1] = v * dt * np.cos(g) / self.wheelbase_m
        return fx, fu

    def sample(self, poses, u, dt, rng):
        v, g = _control(u)
        poses = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
        n = poses.shape[0]
        noise = rng.standard_normal((n, 2))
        return self._step(poses, v + self.sigma_v_mps * noise[:, 0], g + self.sigma_g_rad * noise[:, 1], dt)


@dataclass(frozen=True)
class UnicycleModel:
    """Unicycle of paper 000 Eq. 1; control ``u = (v m/s, omega rad/s)``::

        x += dt v cos(theta);  y += dt v sin(theta);  theta += dt omega

    Control noise: ``v ~ N(v, sigma_v^2)``, ``omega ~ N(omega, sigma_w^2)``.
    """

    sigma_v_mps: float = 0.1
    sigma_w_radps: float = 0.05

    def __post_init__(self) -> None:
        values = (self.sigma_v_mps, self.sigma_w_radps)
        if not (all(is_real(v) and math.isfinite(v) for v in values) and min(values) >= 0):
            raise ValueError(f"invalid unicycle model parameters (finite sigmas >= 0): {self}")

    @property
    def control_cov(self) -> np.ndarray:
        return np.diag([self.sigma_v_mps**2, self.sigma_w_radps**2])

    @staticmethod
    def _step(poses: np.ndarray, v, w, dt: float) -> np.ndarray:
        out = np.empty_like(poses)
        out[:, 0] = poses[:, 0] + dt * v * np.cos(poses[:, 2])
        out[:, 1] = poses[:, 1] + dt * v * np.sin(poses[:, 2])
        out[:, 2] = wrap_angle(poses[:, 2] + dt * w)
        return out

    def mean(self, poses, u, dt):
        v, w = _control(u)
        return self._step(np.asarray(poses, dtype=np.float64).reshape(-1, 3), v, w, dt)

    def jacobians(self, poses, u, dt):
        v, _ = _control(u)
        poses = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
        n = poses.shape[0]
        c, s = np.cos(poses[:, 2]), np.sin(poses[:, 2])
        fx = np.zeros((n, 3, 3))
        fx[:, 0, 0] = fx[:, 1, 1] = fx[:, 2, 2] = 1.0
        fx[:, 0, 2] = -dt * v * s
        fx[:, 1, 2] = dt * v * c
        fu = np.zeros((n, 3, 2))
        fu[:, 0, 0] = dt * c
        fu[:, 1, 0] = dt * s
        fu[:, 2, 1] = dt
        return fx, fu

    def sample(self, poses, u, dt, rng):
        v, w = _control(u)
        poses = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
        noise = rng.standard_normal((poses.shape[0], 2))
        return self._step(poses, v + self.sigma_v_mps * noise[:, 0], w + self.sigma_w_radps * noise[:, 1], dt)
