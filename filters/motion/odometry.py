"""Odometry motion model (Thrun, Burgard & Fox, *Probabilistic Robotics*, Table 5.6).

``sample_motion_model_odometry`` vectorised over an ``(N, 3)`` pose array.

The odometry increment is given as ``delta = (dx, dy, dtheta)`` in the frame of
the *previous* robot pose, i.e. ``filters.pose.relative(odom_prev, odom_now)``.
It is decomposed into a first rotation, a translation and a second rotation::

    trans = hypot(dx, dy)
    rot1  = atan2(dy, dx)            (0 if trans < min_trans_m)
    rot2  = wrap(dtheta - rot1)

Each part is perturbed by zero-mean Gaussian noise whose *variance* is (the form
used by ROS AMCL's ``diff`` model and the 2nd edition of the book)::

    var_rot1  = alpha1 * rot1_n^2 + alpha2 * trans^2
    var_trans = alpha3 * trans^2  + alpha4 * (rot1_n^2 + rot2_n^2)
    var_rot2  = alpha1 * rot2_n^2 + alpha2 * trans^2

Backward motion: driving backwards gives ``rot1 ~ pi``. Taken literally, that
would inflate the rotational noise hugely, so (as AMCL does) the rotation
magnitudes that enter the noise are folded: ``rot_n = min(|rot|, |pi - |rot||)``.
The motion itself still uses the exact ``rot1``/``rot2``, so a backward step
moves the particles backwards with the same noise as a forward step of the same
length.

Note that with variance proportional to the squared increment, the spread
accumulated over a path depends on how finely the path is cut into steps; the
alphas are therefore tuned for a given odometry rate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from filters.numbers import is_real
from filters.pose import finite_increment, wrap_angle, wrap_float

MAX_ALPHA = 100.0
"""Largest odometry noise coefficient taken: its noise's standard deviation is then ten times the motion (a step of
0.05 m moves a particle by 0.5 m, one sigma), past any odometry worth a filter; 1e60 sent particles beyond the pose
rasters' 1e15 m at the first step."""


@dataclass(frozen=True)
class OdometryMotionConfig:
    """Noise parameters of the odometry motion model (dimensionless, as in AMCL).

    Attributes (each alpha in ``[0, MAX_ALPHA]``):
        alpha1: rotation noise from rotation (rad^2 / rad^2).
        alpha2: rotation noise from translation (rad^2 / m^2).
        alpha3: translation noise from translation (m^2 / m^2).
        alpha4: translation noise from rotation (m^2 / rad^2).
        min_trans_m: below this translation, ``rot1`` is taken as 0 (the heading of
            a tiny displacement is meaningless) and the whole heading change goes
            into ``rot2``.
        exact_small_moves: False (as AMCL, every env up to ``SemReloc-v21``, ``SemSlam-v1`` and ``-v0``): that ``rot1 =
            0`` moves the particle too, so a step shorter than ``min_trans_m`` goes along the particle's heading
            whatever its direction: a 5 mm step backwards or sideways is taken 5 mm forwards (an outside audit: 200 such
            steps backwards end 1 m ahead). True: the step moves in its own direction (``rot1 = atan2(dy, dx)``), and
            only the noise takes it as a turn on the spot (its stds those of ``rot1 = 0``): ``SemReloc-v22`` and
            ``SemSlam-v2``, in their simulated odometry and their filters. An older env opts in with
            ``odometry={"exact_small_moves": True}`` (the simulated odometry) and ``relocalizer={"motion":
            {"exact_small_moves": True}}`` (the filter's model).
    """

    alpha1: float = 0.2
    alpha2: float = 0.2
    alpha3: float = 0.2
    alpha4: float = 0.2
    min_trans_m: float = 0.01
    exact_small_moves: bool = False

    def __post_init__(self) -> None:
        if not isinstance(self.exact_small_moves, (bool, np.bool_)):
            raise ValueError(f"OdometryMotionConfig.exact_small_moves must be a bool, got {self.exact_small_moves!r}")
        object.__setattr__(self, "exact_small_moves", bool(self.exact_small_moves))
        for name in ("alpha1", "alpha2", "alpha3", "alpha4", "min_trans_m"):
            v = getattr(self, name)
            if not (is_real(v) and np.isfinite(v) and v >= 0):
                raise ValueError(f"OdometryMotionConfig.{name} must be a finite number >= 0, got {v!r}")
            if name != "min_trans_m" and v > MAX_ALPHA:
                raise ValueError(f"OdometryMotionConfig.{name} must be at most MAX_ALPHA = {MAX_ALPHA:g}, got {v!r}")
            object.__setattr__(self, name, float(v))


def decompose(delta: np.ndarray, min_trans_m: float = 0.01) -> tuple[float, float, float]:
    """Split a robot-frame increment ``(dx, dy, dtheta)`` into ``(rot1, trans, rot2)`` (rad, m, rad)."""
    dx, dy, dth = finite_increment(delta, "odometry delta")
    trans = float(np.hypot(dx, dy))  # NumPy's hypot and arctan2: Python's math rounds differently
    rot1 = float(np.arctan2(dy, dx)) if trans >= min_trans_m else 0.0
    return rot1, trans, wrap_float(dth - rot1)


def _fold(rot: float) -> float:
    """Rotation magnitude that enters the noise: forward and backward motion alike."""
    a = abs(rot)
    return min(a, abs(np.pi - a))


@numba.njit(cache=True, nogil=True, inline="always")
def move_particle(p, i, rot1, trans, rot2, s_r1, s_t, s_r2, noise, out):  # pragma: no cover - compiled
    """``out[i]`` = ``p[i]`` moved by ``(rot1, trans, rot2)`` perturbed by ``noise[:, i]`` (see ``sample``)."""
    heading = p[i, 2] + (rot1 - s_r1 * noise[0, i])
    t = trans - s_t * noise[1, i]
    out[i, 0] = p[i, 0] + t * math.cos(heading)
    out[i, 1] = p[i, 1] + t * math.sin(heading)
    y = heading + (rot2 - s_r2 * noise[2, i]) + math.pi
    # wrap_angle's (y % 2pi) - pi, with the modulo skipped where it is y itself (same bits; +-0 - pi is -pi)
    out[i, 2] = y - math.pi if 0.0 < y < 2.0 * math.pi else y % (2.0 * math.pi) - math.pi


@numba.njit(cache=True, nogil=True)
def _sample_kernel(p, rot1, trans, rot2, s_r1, s_t, s_r2, noise, out):  # pragma: no cover - compiled
    """`move_particle` of every particle ``i`` of ``p``."""
    for i in range(p.shape[0]):
        move_particle(p, i, rot1, trans, rot2, s_r1, s_t, s_r2, noise, out)


class OdometryMotionModel:
    """``sample(poses, delta, rng)``: draw new poses given an odometry increment.

    Stateless apart from its config; all randomness comes from the ``rng`` passed in.
    """

    def __init__(self, config: OdometryMotionConfig | None = None) -> None:
        self.config = config if config is not None else OdometryMotionConfig()

    def stds(self, delta: np.ndarray) -> tuple[float, float, float]:
        """Standard deviations ``(rot1 rad, trans m, rot2 rad)`` of the noise for ``delta``."""
        return self.parts(delta)[3:]

    def parts(self, delta) -> tuple[float, float, float, float, float, float]:
        """``(rot1, trans, rot2, std rot1, std trans, std rot2)`` of the increment ``delta``: the motion and its
        noise (they differ for a step under ``min_trans_m`` with ``exact_small_moves``)."""
        c = self.config
        rot1, trans, rot2 = decompose(delta, c.min_trans_m)
        stds = self._stds(rot1, trans, rot2)
        if c.exact_small_moves and 0.0 < trans < c.min_trans_m:
            dx, dy, _ = finite_increment(delta, "odometry delta")
            exact = float(np.arctan2(dy, dx))
            return exact, trans, wrap_float(rot1 + rot2 - exact), *stds
        return rot1, trans, rot2, *stds

    def _stds(self, rot1: float, trans: float, rot2: float) -> tuple[float, float, float]:
        """`stds` of the decomposed increment ``(rot1, trans, rot2)``."""
        c = self.config
        r1, r2 = _fold(rot1), _fold(rot2)
        var_r1 = c.alpha1 * r1 * r1 + c.alpha2 * trans * trans
        var_t = c.alpha3 * trans * trans + c.alpha4 * (r1 * r1 + r2 * r2)
        var_r2 = c.alpha1 * r2 * r2 + c.alpha2 * trans * trans
        return math.sqrt(var_r1), math.sqrt(var_t), math.sqrt(var_r2)  # correctly rounded, as np.sqrt

    def sample(self, poses: np.ndarray, delta: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """New ``(N, 3)`` poses: each of ``poses`` moved by a noisy copy of ``delta``.

        Args:
            poses: ``(N, 3)`` particle poses ``(x m, y m, theta rad)``.
            delta: ``(3,)`` odometry increment ``(dx m, dy m, dtheta rad)`` in the previous robot frame.
            rng: the generator every draw comes from (3 normal draws of size N, in the
                order rot1, trans, rot2).

        Returns:
            A new ``(N, 3)`` float64 array, headings wrapped to ``[-pi, pi)``.
        """
        if not isinstance(rng, np.random.Generator):
            raise TypeError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
        p = np.asarray(poses, dtype=np.float64)
        if p.ndim != 2 or p.shape[1] != 3:
            raise ValueError(f"poses must have shape (N, 3), got {p.shape}")
        rot1, trans, rot2, s_r1, s_t, s_r2 = self.parts(delta)
        noise = rng.standard_normal((3, p.shape[0]))
        out = np.empty_like(p)
        _sample_kernel(np.ascontiguousarray(p), rot1, trans, rot2, s_r1, s_t, s_r2, noise, out)
        return out

    def sample_reference(self, poses: np.ndarray, delta: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """`sample` as plain NumPy array code (the reference the compiled kernel is tested against)."""
        p = np.asarray(poses, dtype=np.float64)
        rot1, trans, rot2, s_r1, s_t, s_r2 = self.parts(delta)
        n = p.shape[0]
        noise = rng.standard_normal((3, n))
        r1 = rot1 - s_r1 * noise[0]
        t = trans - s_t * noise[1]
        r2 = rot2 - s_r2 * noise[2]
        heading = p[:, 2] + r1
        out = np.empty_like(p)
        out[:, 0] = p[:, 0] + t * np.cos(heading)
        out[:, 1] = p[:, 1] + t * np.sin(heading)
        out[:, 2] = wrap_angle(heading + r2)
        return out

    def sample_pose(self, pose, delta, rng: np.random.Generator) -> np.ndarray:
        """`sample` for a single pose ``(3,)``, without the particle-array overhead.

        Draws the same 3 normals in the same order and returns the same numbers bit for bit
        as ``sample(pose[None], delta, rng)[0]`` (scalar arithmetic with NumPy's ``arctan2`` /
        ``hypot`` where Python's ``math`` rounds differently).
        """
        if not isinstance(rng, np.random.Generator):
            raise TypeError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
        p = np.asarray(pose, dtype=np.float64).reshape(-1)
        if p.shape != (3,):
            raise ValueError(f"pose must have shape (3,), got {np.shape(pose)}")
        x, y, th = p.tolist()
        rot1, trans, rot2, s_r1, s_t, s_r2 = self.parts(delta)
        n0, n1, n2 = rng.standard_normal(3).tolist()
        heading = th + (rot1 - s_r1 * n0)
        t = trans - s_t * n1
        return np.array(
            [x + t * math.cos(heading), y + t * math.sin(heading), wrap_float(heading + (rot2 - s_r2 * n2))]
        )
