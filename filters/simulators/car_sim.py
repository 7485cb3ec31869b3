"""The car-like landmark-SLAM simulator of Tim Bailey's ``ekfslam_v1`` / ``fastslam`` packages.

A bicycle-model vehicle (wheelbase ``L``) drives at constant speed ``V``; each
control step (``dt_control_s``) the steering angle ``G`` turns toward the current
waypoint, limited in rate (``max_steer_rate_radps``) and angle (``max_steer_rad``);
a waypoint counts as reached within ``at_waypoint_m``. Every ``dt_observe_s``
a forward-facing range-bearing sensor sees the landmarks within ``max_range_m``
in the forward half-plane. The filter gets the controls with additive Gaussian
noise (``sigma_v_mps``, ``sigma_g_rad``) and noisy observations (``sigma_r_m``,
``sigma_b_rad``) together with the true landmark ids (for known association).

Vehicle model (Bailey's ``vehicle_model.m``)::

    x += V dt cos(G + theta);  y += V dt sin(G + theta);  theta += V dt sin(G) / L

Defaults follow Bailey's ``configfile.m``. The built-in course (`default_course`)
is ours: a 100 m x 80 m area, 15 waypoints, 31 landmarks, start at (0, 0) heading
east, driven clockwise (the layout paper 001 describes); it has no randomness.
All random draws come from the ``rng`` passed to `simulate`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from filters.pose import wrap_angle


@dataclass(frozen=True)
class CarSimConfig:
    """Simulator settings (Bailey's defaults); units in the names."""

    speed_mps: float = 3.0
    wheelbase_m: float = 4.0
    max_steer_rad: float = math.radians(30.0)
    max_steer_rate_radps: float = math.radians(20.0)
    dt_control_s: float = 0.025
    dt_observe_s: float = 0.2
    max_range_m: float = 30.0
    at_waypoint_m: float = 1.0
    sigma_v_mps: float = 0.3
    sigma_g_rad: float = math.radians(3.0)
    sigma_r_m: float = 0.1
    sigma_b_rad: float = math.radians(1.0)
    n_loops: int = 1
    max_steps: int | None = None
    control_noise: bool = True
    sensor_noise: bool = True

    def __post_init__(self) -> None:
        positive = [
            self.speed_mps,
            self.wheelbase_m,
            self.max_steer_rad,
            self.max_steer_rate_radps,
            self.dt_control_s,
            self.dt_observe_s,
            self.max_range_m,
            self.at_waypoint_m,
        ]
        if not all(p > 0 for p in positive):
            raise ValueError(f"simulator lengths, rates and times must be positive: {self}")
        if min(self.sigma_v_mps, self.sigma_g_rad, self.sigma_r_m, self.sigma_b_rad) < 0:
            raise ValueError("noise standard deviations must be >= 0")
        if self.n_loops < 1 or (self.max_steps is not None and self.max_steps < 1):
            raise ValueError("n_loops and max_steps must be >= 1")

    @property
    def observe_every(self) -> int:
        """Control steps per observation (8 with the defaults)."""
        return max(1, round(self.dt_observe_s / self.dt_control_s))


@dataclass(frozen=True)
class Course:
    """Waypoints ``(W, 2)`` (m) driven in order, true landmarks ``(M, 2)`` (m), start pose ``(3,)``."""

    waypoints: np.ndarray
    landmarks: np.ndarray
    start_pose: np.ndarray


def _landmarks_along(waypoints: np.ndarray, start: np.ndarray, n: int, offsets_m: list[float]) -> np.ndarray:
    """``n`` landmarks spaced evenly in arc length along the closed polyline, offset sideways."""
    pts = np.vstack([start[None, :2], waypoints, start[None, :2]])
    seg = np.diff(pts, axis=0)
    seg_len = np.hypot(seg[:, 0], seg[:, 1])
    cum = np.concatenate([[0.0], np.cumsum(seg_len)])
    out = []
    for i in range(n):
        s = (i + 0.5) * cum[-1] / n
        k = min(int(np.searchsorted(cum, s, side="right")) - 1, seg.shape[0] - 1)
        t = (s - cum[k]) / seg_len[k]
        p = pts[k] + t * seg[k]
        normal = np.array([-seg[k, 1], seg[k, 0]]) / seg_len[k]  # left of travel
        out.append(p + offsets_m[i % len(offsets_m)] * normal)
    return np.array(out)


def default_course() -> Course:
    """100 m x 80 m area (x in [-10, 90], y in [-70, 10]), 15 waypoints, 31 landmarks, clockwise from (0, 0)."""
    waypoints = np.array(
        [
            [20.0, 2.0],
            [40.0, -2.0],
            [60.0, 2.0],
            [78.0, -4.0],  # east along the top
            [83.0, -20.0],
            [78.0, -38.0],
            [83.0, -55.0],  # south down the right side
            [66.0, -62.0],
            [46.0, -57.0],
            [26.0, -63.0],
            [6.0, -58.0],  # west along the bottom
            [-3.0, -44.0],
            [2.0, -28.0],
            [-3.0, -12.0],
            [0.0, 0.0],  # north back to the start
        ]
    )
    start = np.array([0.0, 0.0, 0.0])
    offsets = [7.0, -9.0, 11.0, -6.0, 9.0, -12.0, 6.0, -8.0, 12.0, -7.0]
    lms = _landmarks_along(waypoints, start, 31, offsets)
    lms[:, 0] = np.clip(lms[:, 0], -10.0, 90.0)
    lms[:, 1] = np.clip(lms[:, 1], -70.0, 10.0)
    return Course(waypoints, lms, start)


def small_course() -> Course:
    """A 30 m x 20 m loop with 4 waypoints and 8 landmarks, clockwise from (0, 0), for fast tests."""
    waypoints = np.array([[20.0, 0.0], [25.0, -12.0], [5.0, -18.0], [0.0, 0.0]])
    start = np.array([0.0, 0.0, 0.0])
    lms = _landmarks_along(waypoints, start, 8, [6.0, -6.0, 8.0, -5.0])
    return Course(waypoints, lms, start)


@dataclass(frozen=True)
class CarSimRun:
    """One simulated drive.

    true_poses ``(T+1, 3)``: pose before step 0 and after each of the ``T`` control steps.
    controls_true ``(T, 2)`` and controls ``(T, 2)`` (what the filter sees): ``(V m/s, G rad)``.
    obs_steps ``(S,)``: control-step index ``t`` after which scan ``s`` was taken (pose ``true_poses[t + 1]``).
    observations: ``S`` arrays ``(K_s, 2)`` of ``(range_m, bearing_rad)``; observation_ids: ``S`` arrays ``(K_s,)``.
    landmarks ``(M, 2)``: the true map. waypoint_reached ``(W * n_loops,)``: step at which each waypoint
    was reached (-1 if never). dt_control_s: the control period.
    """

    true_poses: np.ndarray
    controls_true: np.ndarray
    controls: np.ndarray
    obs_steps: np.ndarray
    observations: tuple
    observation_ids: tuple
    landmarks: np.ndarray
    waypoint_reached: np.ndarray
    dt_control_s: float

    @property
    def n_steps(self) -> int:
        return int(self.controls.shape[0])

    def scans_by_step(self) -> dict[int, tuple[np.ndarray, np.ndarray]]:
        """``{control step t: (z, ids)}``."""
        return {int(t): (z, i) for t, z, i in zip(self.obs_steps, self.observations, self.observation_ids, strict=True)}


def observe(pose: np.ndarray, landmarks: np.ndarray, max_range_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Noise-free ``(z (K, 2), ids (K,))`` of the landmarks within range in the forward half-plane."""
    dx = landmarks[:, 0] - pose[0]
    dy = landmarks[:, 1] - pose[1]
    ok = (dx * math.cos(pose[2]) + dy * math.sin(pose[2]) > 0) & (dx * dx + dy * dy < max_range_m**2)
    ids = np.flatnonzero(ok)
    z = np.stack([np.hypot(dx[ids], dy[ids]), wrap_angle(np.arctan2(dy[ids], dx[ids]) - pose[2])], axis=-1)
    return z.reshape(-1, 2), ids.astype(np.int64)


def simulate(config: CarSimConfig, course: Course, rng: np.random.Generator) -> CarSimRun:
    """Drive ``course`` ``config.n_loops`` times (or ``config.max_steps`` control steps if that ends first)."""
    c = config
    wps = course.waypoints
    n_wp = wps.shape[0]
    x, y, th = (float(v) for v in course.start_pose)
    g = 0.0
    iwp, loop = 0, 0
    dt = c.dt_control_s
    every = c.observe_every
    poses = [(x, y, th)]
    u_true, u_noisy, obs_steps, obs, obs_ids = [], [], [], [], []
    reached = np.full(n_wp * c.n_loops, -1, dtype=np.int64)
    limit = c.max_steps if c.max_steps is not None else 10**7
    t = 0
    while t < limit:
        # steering toward the current waypoint (Bailey's compute_steering.m)
        wx, wy = wps[iwp]
        if (wx - x) ** 2 + (wy - y) ** 2 < c.at_waypoint_m**2:
            reached[loop * n_wp + iwp] = t
            iwp += 1
            if iwp == n_wp:
                loop += 1
                iwp = 0
                if loop == c.n_loops:
                    break
            wx, wy = wps[iwp]
        dg = float(wrap_angle(math.atan2(wy - y, wx - x) - th - g))
        max_dg = c.max_steer_rate_radps * dt
        dg = max(-max_dg, min(max_dg, dg))
        g = max(-c.max_steer_rad, min(c.max_steer_rad, g + dg))
        v = c.speed_mps
        x += v * dt * math.cos(g + th)
        y += v * dt * math.sin(g + th)
        th = float(wrap_angle(th + v * dt * math.sin(g) / c.wheelbase_m))
        poses.append((x, y, th))
        u_true.append((v, g))
        if c.control_noise:
            n = rng.standard_normal(2)
            u_noisy.append((v + c.sigma_v_mps * n[0], g + c.sigma_g_rad * n[1]))
        else:
            u_noisy.append((v, g))
        if (t + 1) % every == 0:
            z, ids = observe(np.array([x, y, th]), course.landmarks, c.max_range_m)
            if c.sensor_noise and ids.size:
                z = z + rng.standard_normal(z.shape) * np.array([c.sigma_r_m, c.sigma_b_rad])
                z[:, 0] = np.abs(z[:, 0])
                z[:, 1] = wrap_angle(z[:, 1])
            obs_steps.append(t)
            obs.append(z)
            obs_ids.append(ids)
        t += 1
    return CarSimRun(
        true_poses=np.array(poses),
        controls_true=np.array(u_true).reshape(-1, 2),
        controls=np.array(u_noisy).reshape(-1, 2),
        obs_steps=np.array(obs_steps, dtype=np.int64),
        observations=tuple(obs),
        observation_ids=tuple(obs_ids),
        landmarks=course.landmarks.copy(),
        waypoint_reached=reached,
        dt_control_s=dt,
    )


def run_slam(slam, run: CarSimRun, on_scan: Callable[[object, int], None] | None = None) -> np.ndarray:
    """Drive a landmark-SLAM filter through ``run``; position error (m) right after each scan's update.

    ``slam`` is any filter with ``predict(control, dt_s)``, ``update(z, ids)`` and ``estimate().pose``
    (FastSLAM and its subclasses, EKF-SLAM). Each control step ``t`` is predicted with
    ``run.controls[t]``; after a step with a scan the filter is updated with ``(z, ids)``, the error
    ``|estimate().pose[:2] - run.true_poses[t + 1, :2]|`` recorded, and ``on_scan(slam, t)`` called
    if given. Returns shape ``(len(run.obs_steps),)``; ``slam.estimate()`` afterwards is the final map.
    """
    scans = run.scans_by_step()
    errs = np.empty(len(scans))
    s = 0
    for t in range(run.n_steps):
        slam.predict(run.controls[t], run.dt_control_s)
        if t in scans:
            slam.update(*scans[t])
            p = slam.estimate().pose
            errs[s] = math.hypot(p[0] - run.true_poses[t + 1, 0], p[1] - run.true_poses[t + 1, 1])
            s += 1
            if on_scan is not None:
                on_scan(slam, t)
    return errs
