"""Grid builders of the mapping run (paper 004 §2): log-odds occupancy and Bayesian semantic grids.

Both mappers take scans at *known* poses — from the simulator's mapping run, or logged on a
real robot (SLAM poses + lidar / semantic pseudo-laser) — and accumulate independent
per-cell log-odds (paper 004 Eq. 5: the map posterior factorises over cells; Eq. 6: each
cell's Bayes update, which in log-odds form is a sum of per-frame increments
``l <- clip(l + delta, l_min, l_max)``, prior ``l = 0``, i.e. ``p = 0.5``).

* `OccupancyMapper` (lidar, `LaserScan`): every cell a beam
  passes through gets ``l_free``, the cell its return lies in gets ``l_occ``. A beam
  without a return (``range >= range_max_m``) clears cells up to ``range_max_m`` and marks
  nothing; for a lidar whose dropouts read as no return, `OccupancyMapper.clear_unobserved` is a
  second pass in which such beams clear only cells nothing observed, up to the first surface.
* `SemanticMapper` (semantic pseudo-laser, `SemanticScan`), one
  log-odds grid per class. A beam labelled ``k + 1`` ("inside a detection") raises class
  ``k`` at its end cell by ``l_hit`` and lowers every other class there by ``l_other_hit``;
  the cells on its way get the small decrement ``l_free_inside`` (paper 004 Fig. 4,
  light-grey region). A beam labelled ``0`` (outside every detection box, dark-grey region)
  lowers every class by the larger ``l_free_outside`` along its way and by
  ``l_unlabelled_end`` at its end cell: its return is a surface the detector saw and did
  not call an object.

Geometry. A scan's sensor sits at ``scan.sensor_pose`` in the robot frame (default the robot
centre); beam ``i`` of a scan at robot pose ``P`` runs from the sensor's world position
``(sx, sy, sth) = P ⊕ sensor_pose`` at world angle ``sth + angles[i]``. Lidar beams below the
scan's ``range_min_m`` are invalid and update nothing. Its cells are the exact
4-connected traversal of the segment (Amanatides & Woo DDA, compiled with numba; see
`beam_cells`); a cell is listed once per beam, so a beam updates a cell at most once.
Several beams of one scan do update a cell several times. A range that ends exactly on
a cell face counts the cell being entered (tolerance ``1e-6`` cell), so ranges reported
as "distance to the boundary of the hit cell" (e.g. `filters.simulators.grid_raycast`) mark that cell.
Beams and cells outside the raster are skipped.

The mappers own a raster fixed up front (shape, resolution, origin, as in
`GridMap`); `to_grid` turns the log-odds into a ``GridMap``.
No randomness anywhere.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numba
import numpy as np
from scipy import ndimage
from scipy.special import expit

from filters.mapping.grid import DEFAULT_CLASS_NAMES, GridMap
from filters.numbers import is_int_dtype, is_real
from filters.pose import compose
from filters.robot_data.scans import LaserScan, SemanticScan

__all__ = [
    "OccupancyParams",
    "SemanticParams",
    "OccupancyMapper",
    "SemanticMapper",
    "beam_cells",
    "build_grid_map",
]

_END_TOL_CELLS = 1e-6


# ------------------------------------------------------------------------------------------------ parameters
def _finite(name: str, v: float) -> None:
    if not (is_real(v) and math.isfinite(v)):
        raise ValueError(f"{name} must be a finite number, got {v!r}")


@dataclass(frozen=True)
class OccupancyParams:
    """Log-odds increments of the occupancy mapper (defaults: OctoMap's, Hornung et al. 2013).

    Attributes:
        l_occ: added at the end cell of a beam with a return; ``> 0``. Default ``0.85``
            (``p_hit = 0.7``): one hit makes an unknown cell occupied under the 0.65 threshold.
        l_free: added at each cell a beam passes through (and, for a beam without a
            return, every cell up to its maximum range); ``< 0``. Default ``-0.4`` (``p_miss = 0.4``):
            four passes make an unknown cell free under the 0.196 threshold.
        l_min, l_max: clamp after every cell update, ``l_min < 0 < l_max``. Defaults ``-2.0`` and ``3.5``
            (``p = 0.12`` and ``0.97``): keeps the map able to change (a moved obstacle is
            cleared by about nine passes).
        max_range_m: beams are used up to this length, metres; a longer return clears up
            to ``max_range_m`` and marks nothing. Default ``inf``: the scan's own ``range_max_m``.
        clear_no_return: beams without a return (``range >= scan.range_max_m``) clear their
            cells up to the limit (default True). Set False for a lidar whose dropouts read as
            no return although a surface is in range: a dropout would otherwise clear the wall
            it missed and the space behind it. Returns beyond ``max_range_m`` are real returns
            and clear up to ``max_range_m`` either way.
        l_free_unobserved: the most log-odds a cell keeps once a no-return beam of
            `OccupancyMapper.clear_unobserved` crossed it; ``< 0``. Default ``-1.6`` (four ``l_free``, ``p =
            0.17``: free under the 0.196 threshold): such a beam is no dropout (it stops at the first known
            surface), and the space it clears is where returns pass too rarely to make cells free.
    """

    l_occ: float = 0.85
    l_free: float = -0.4
    l_min: float = -2.0
    l_max: float = 3.5
    max_range_m: float = math.inf
    clear_no_return: bool = True
    l_free_unobserved: float = -1.6

    def __post_init__(self) -> None:
        for name in ("l_occ", "l_free", "l_min", "l_max", "l_free_unobserved"):
            _finite(name, getattr(self, name))
        if not self.l_occ > 0:
            raise ValueError(f"l_occ must be > 0, got {self.l_occ}")
        if not self.l_free < 0:
            raise ValueError(f"l_free must be < 0, got {self.l_free}")
        if not self.l_min < 0 < self.l_max:
            raise ValueError(f"need l_min < 0 < l_max, got {self.l_min}, {self.l_max}")
        if not self.l_min <= self.l_free_unobserved < 0:
            raise ValueError(f"need l_min <= l_free_unobserved < 0, got {self.l_min}, {self.l_free_unobserved}")
        if not self.max_range_m > 0:
            raise ValueError(f"max_range_m must be > 0, got {self.max_range_m}")


@dataclass(frozen=True)
class SemanticParams:
    """Log-odds increments of the semantic mapper (paper 004 §2, Eq. 5-6, Fig. 4).

    The paper gives no numbers, only the order ``l_free_outside < l_free_inside < 0 < l_hit``;
    the defaults match `OccupancyParams` for hits.

    Attributes:
        l_hit: added to class ``k`` at the end cell of a beam labelled ``k + 1``; ``> 0``.
            Default ``0.85``: one labelled hit makes the cell that class (threshold 0.5).
        l_other_hit: added to every *other* class at that end cell; ``<= 0``. Default ``-0.4``.
        l_free_inside: added to every class along the free part of a labelled beam (inside a
            detection box: light grey); ``<= 0``. Default ``-0.2``.
        l_free_outside: added to every class along a beam labelled 0 (outside every detection:
            dark grey, "more likely empty"); ``< l_free_inside``. Default ``-0.6``.
        l_unlabelled_end: added to every class at the end cell of a returned beam labelled 0
            (a surface seen and not detected as an object); ``<= 0``. Default ``-0.6``; use a
            smaller magnitude if detections are often narrower than the objects.
        l_min, l_max: clamp after every cell update, ``l_min < 0 < l_max``. Defaults ``-2.0``, ``3.5``.
        max_range_m: beams are used up to this length, metres (see `OccupancyParams`);
            default ``inf``: the scan's own ``range_max_m``.
        clear_no_return: beams without a return (``range >= scan.range_max_m``) lower every class up
            to the limit (default True). Set False for a camera whose too-close returns read as no
            return (a depth camera below its minimum range): such a beam would otherwise clear the
            object in front of it and everything behind it, up to the camera's range.
    """

    l_hit: float = 0.85
    l_other_hit: float = -0.4
    l_free_inside: float = -0.2
    l_free_outside: float = -0.6
    l_unlabelled_end: float = -0.6
    l_min: float = -2.0
    l_max: float = 3.5
    max_range_m: float = math.inf
    clear_no_return: bool = True

    def __post_init__(self) -> None:
        for name in ("l_hit", "l_other_hit", "l_free_inside", "l_free_outside", "l_unlabelled_end", "l_min", "l_max"):
            _finite(name, getattr(self, name))
        if not self.l_hit > 0:
            raise ValueError(f"l_hit must be > 0, got {self.l_hit}")
        if not (self.l_other_hit <= 0 and self.l_unlabelled_end <= 0):
            raise ValueError("l_other_hit and l_unlabelled_end must be <= 0")
        if not self.l_free_outside < self.l_free_inside <= 0:
            raise ValueError(
                "need l_free_outside < l_free_inside <= 0 (outside a detection lowers a class more, paper 004), "
                f"got {self.l_free_outside}, {self.l_free_inside}"
            )
        if not self.l_min < 0 < self.l_max:
            raise ValueError(f"need l_min < 0 < l_max, got {self.l_min}, {self.l_max}")
        if not self.max_range_m > 0:
            raise ValueError(f"max_range_m must be > 0, got {self.max_range_m}")


# ------------------------------------------------------------------------------------------- ray traversal
@numba.njit(cache=True, nogil=True, error_model="numpy")
def _walk(u0, v0, du, dv, t_end, out_r, out_c, out_t):  # pragma: no cover - compiled
    """Cells from the one holding ``(u0, v0)`` (cell units: u = column, v = row) along unit ``(du, dv)``.

    Lists each cell entered at parameter ``t <= t_end + tol`` (cell units) with its entry
    parameter; returns how many were written (at most ``len(out_r)``). At an exact corner the
    row step is taken first. Entry parameters are recomputed from the start point at every
    step, so there is no accumulated drift.
    """
    c = math.floor(u0)
    r = math.floor(v0)
    step_c = 1 if du > 0.0 else (-1 if du < 0.0 else 0)
    step_r = 1 if dv > 0.0 else (-1 if dv < 0.0 else 0)
    limit = t_end + 1e-6
    cap = out_r.shape[0]
    out_r[0] = r
    out_c[0] = c
    out_t[0] = 0.0
    n = 1
    while n < cap:
        if step_c > 0:
            tc = (c + 1 - u0) / du
        elif step_c < 0:
            tc = (c - u0) / du
        else:
            tc = np.inf
        if step_r > 0:
            tr = (r + 1 - v0) / dv
        elif step_r < 0:
            tr = (r - v0) / dv
        else:
            tr = np.inf
        if tr <= tc:
            if tr > limit:
                break
            r += step_r
            out_t[n] = tr
        else:
            if tc > limit:
                break
            c += step_c
            out_t[n] = tc
        out_r[n] = r
        out_c[n] = c
        n += 1
    return n


def _buffers(t_end_max: float):
    cap = int(1.5 * t_end_max) + 4  # a segment of length t crosses at most |du| t + |dv| t + 2 <= 1.42 t + 2 cells
    return np.empty(cap, np.int64), np.empty(cap, np.int64), np.empty(cap, np.float64)


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _occupancy_kernel(L, ended, u0, v0, du, dv, t_end, hit, l_free, l_occ, lo, hi, br, bc, bt):  # pragma: no cover
    h, w = L.shape
    for b in range(u0.shape[0]):
        n = _walk(u0[b], v0[b], du[b], dv[b], t_end[b], br, bc, bt)
        for j in range(n):
            r = br[j]
            c = bc[j]
            if r < 0 or r >= h or c < 0 or c >= w:
                continue
            end = hit[b] and j == n - 1
            if end:
                ended[r, c] = True
            d = l_occ if end else l_free
            x = L[r, c] + d
            L[r, c] = lo if x < lo else (hi if x > hi else x)
    return 0


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _no_return_kernel(L, blocked, u0, v0, du, dv, t_end, l_at_most, br, bc, bt):  # pragma: no cover - compiled
    h, w = L.shape
    for b in range(u0.shape[0]):
        n = _walk(u0[b], v0[b], du[b], dv[b], t_end[b], br, bc, bt)
        entered = False
        for j in range(n):
            r = br[j]
            c = bc[j]
            if r < 0 or r >= h or c < 0 or c >= w:
                if entered:  # a straight beam that left the raster does not come back
                    break
                continue
            entered = True
            if blocked[r, c]:
                break
            if L[r, c] > l_at_most:
                L[r, c] = l_at_most
    return 0


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _semantic_kernel(
    L, u0, v0, du, dv, t_end, end_label, free_delta, l_hit, l_other, l_unl_end, lo, hi, br, bc, bt
):  # pragma: no cover - compiled
    h, w, n_cls = L.shape
    for b in range(u0.shape[0]):
        n = _walk(u0[b], v0[b], du[b], dv[b], t_end[b], br, bc, bt)
        for j in range(n):
            r = br[j]
            c = bc[j]
            if r < 0 or r >= h or c < 0 or c >= w:
                continue
            lab = end_label[b] if j == n - 1 else -1
            if lab <= 0:  # the same increment for every class (a straight loop the compiler vectorises)
                d = free_delta[b] if lab < 0 else l_unl_end
                for k in range(n_cls):
                    x = L[r, c, k] + d
                    L[r, c, k] = lo if x < lo else (hi if x > hi else x)
            else:
                for k in range(n_cls):
                    x = L[r, c, k] + (l_hit if lab == k + 1 else l_other)
                    L[r, c, k] = lo if x < lo else (hi if x > hi else x)
    return 0


def beam_cells(
    start_xy_m, end_xy_m, resolution_m: float, origin_xy_m=(0.0, 0.0)
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The cells a straight beam from ``start_xy_m`` to ``end_xy_m`` (metres) passes through, in order.

    The traversal the mappers use. Returns ``rows, cols`` (int64; not clipped to any grid) and
    ``t_m``, the distance from the start at which each cell is entered (``0`` for the start
    cell). The last cell holds the end point, or is entered exactly at it.
    """
    if not resolution_m > 0:
        raise ValueError(f"resolution_m must be positive, got {resolution_m!r}")
    p0 = np.asarray(start_xy_m, dtype=np.float64).reshape(2)
    p1 = np.asarray(end_xy_m, dtype=np.float64).reshape(2)
    u0 = (p0[0] - origin_xy_m[0]) / resolution_m
    v0 = (p0[1] - origin_xy_m[1]) / resolution_m
    length = float(np.hypot(*(p1 - p0)))
    if length == 0.0:
        return np.array([math.floor(v0)]), np.array([math.floor(u0)]), np.zeros(1)
    du, dv = (p1 - p0) / length
    br, bc, bt = _buffers(length / resolution_m)
    n = _walk(u0, v0, du, dv, length / resolution_m, br, bc, bt)
    return br[:n].copy(), bc[:n].copy(), bt[:n] * resolution_m


# ----------------------------------------------------------------------------------------------------- mappers
class _RasterMapper:
    """Raster bookkeeping and beam geometry shared by both mappers."""

    @staticmethod
    def _drop_no_return(beams: tuple, *per_beam: np.ndarray) -> tuple | None:
        """``beams`` (as `_beams` gives them) followed by the ``per_beam`` arrays, all without the sensor's
        no-return beams (``clear_no_return=False``: such a beam updates nothing); None if no beam is left."""
        keep = ~beams[6]
        if not keep.any():
            return None
        return tuple(a[keep] for a in (*beams, *per_beam))

    def __init__(self, shape: tuple[int, int], resolution_m: float, origin_xy_m=(0.0, 0.0)) -> None:
        shape = tuple(int(s) for s in shape)
        if len(shape) != 2 or min(shape) <= 0:
            raise ValueError(f"shape must be (rows, cols) > 0, got {shape}")
        if not (np.isfinite(resolution_m) and resolution_m > 0):
            raise ValueError(f"resolution_m must be a positive number, got {resolution_m!r}")
        origin = tuple(float(v) for v in origin_xy_m)
        if len(origin) != 2 or not all(math.isfinite(v) for v in origin):
            raise ValueError(f"origin_xy_m must be two finite numbers, got {origin_xy_m!r}")
        self._shape: tuple[int, int] = shape  # type: ignore[assignment]
        self._res = float(resolution_m)
        self._origin: tuple[float, float] = origin  # type: ignore[assignment]

    @property
    def shape(self) -> tuple[int, int]:
        """``(H, W)`` of the raster."""
        return self._shape

    @property
    def resolution_m(self) -> float:
        """Cell edge in metres."""
        return self._res

    @property
    def origin_xy_m(self) -> tuple[float, float]:
        """World ``(x, y)`` of the lower-left corner of cell ``(0, 0)``, metres."""
        return self._origin

    def _planes(self) -> np.ndarray:
        """The log-odds as ``(H, W)`` or ``(C, H, W)`` (a view)."""
        return self._L

    @property
    def logodds(self) -> np.ndarray:
        """Log-odds, read-only view (0 = unknown): ``(H, W)`` occupancy or ``(C, H, W)`` per class (the
        semantic mapper stores classes innermost, so its view is not C-contiguous)."""
        v = self._planes().view()
        v.setflags(write=False)
        return v

    def probabilities(self) -> np.ndarray:
        """``1 / (1 + exp(-logodds))``: probability of occupied (``(H, W)``) or of each class (``(C, H, W)``)."""
        return np.ascontiguousarray(expit(self._planes()))

    def _same_raster(self, other: _RasterMapper | GridMap) -> bool:
        return (
            tuple(other.shape) == self._shape
            and float(other.resolution_m) == self._res
            and tuple(other.origin_xy_m) == self._origin
        )

    def _beams(self, poses: np.ndarray, scans: Sequence, max_range_m: float, labels: np.ndarray | None = None):
        """Concatenate the beams of ``scans`` into cell-unit start points, directions, lengths and returns.

        Beams below a scan's ``range_min_m`` are left out; ``labels`` (one per beam of ``scans``, in order),
        if given, are left out with them and returned after the beams: ``(beams, labels)``."""
        poses = np.asarray(poses, dtype=np.float64)
        if poses.ndim != 2 or poses.shape[1] != 3:
            raise ValueError(f"poses must have shape (N, 3), got {poses.shape}")
        if poses.shape[0] != len(scans):
            raise ValueError(f"got {poses.shape[0]} poses but {len(scans)} scans")
        if not np.all(np.isfinite(poses)):
            raise ValueError("poses must be finite")
        counts = np.array([s.ranges.size for s in scans], dtype=np.int64)
        if counts.sum() == 0:
            return None
        ranges = np.concatenate([s.ranges for s in scans])
        angles = np.concatenate([s.angles for s in scans])
        rmax = np.repeat(np.array([s.range_max_m for s in scans], dtype=np.float64), counts)
        rmin = np.repeat(np.array([getattr(s, "range_min_m", 0.0) for s in scans], dtype=np.float64), counts)
        sensor = compose(poses, np.array([s.sensor_pose for s in scans], dtype=np.float64))
        p = np.repeat(sensor, counts, axis=0)
        use = np.minimum(rmax, max_range_m)
        no_return = ranges >= rmax
        returned = ~no_return & (ranges <= use)
        length = np.where(returned, ranges, use)
        th = p[:, 2] + angles
        u0 = (p[:, 0] - self._origin[0]) / self._res
        v0 = (p[:, 1] - self._origin[1]) / self._res
        t_end = length / self._res
        ok = ranges >= rmin  # below the sensor's minimum range: invalid, no update
        if not ok.all():
            u0, v0, th, t_end, returned, no_return = (a[ok] for a in (u0, v0, th, t_end, returned, no_return))
            labels = None if labels is None else labels[ok]
            if t_end.size == 0:
                return None
        beams = (u0, v0, np.cos(th), np.sin(th), t_end, returned, no_return)
        return beams if labels is None else (beams, labels)

    def _beam_arrays(self, poses, ranges, angles, range_max_m: float, max_range_m: float):
        """`_beams` for scans given as arrays: ``ranges (N, B)``, ``angles (B,)`` or ``(N, B)``
        (sensor at the robot centre, no minimum range)."""
        poses = np.asarray(poses, dtype=np.float64)
        r = np.asarray(ranges, dtype=np.float64)
        if poses.ndim != 2 or poses.shape[1] != 3 or not np.all(np.isfinite(poses)):
            raise ValueError(f"poses must be finite with shape (N, 3), got {poses.shape}")
        if r.ndim != 2 or r.shape[0] != poses.shape[0]:
            raise ValueError(f"ranges must have shape (N, B) with N = {poses.shape[0]} poses, got {r.shape}")
        try:
            a = np.broadcast_to(np.asarray(angles, dtype=np.float64), r.shape)
        except ValueError:
            raise ValueError(f"angles {np.shape(angles)} do not match ranges {r.shape}") from None
        if not (np.all(np.isfinite(r)) and np.all(r >= 0) and np.all(np.isfinite(a))):
            raise ValueError("ranges must be finite and >= 0, angles finite")
        if not (math.isfinite(range_max_m) and range_max_m > 0):
            raise ValueError(f"range_max_m must be positive, got {range_max_m!r}")
        if r.size == 0:
            return None
        use = min(float(range_max_m), max_range_m)
        no_return = (r >= range_max_m).ravel()
        returned = ~no_return & (r <= use).ravel()
        length = np.where(returned, r.ravel(), use)
        th = (poses[:, 2:3] + a).ravel()
        u0 = np.repeat((poses[:, 0] - self._origin[0]) / self._res, r.shape[1])
        v0 = np.repeat((poses[:, 1] - self._origin[1]) / self._res, r.shape[1])
        return u0, v0, np.cos(th), np.sin(th), length / self._res, returned, no_return

    @staticmethod
    def _one(pose, scan) -> tuple[np.ndarray, list]:
        pose = np.asarray(pose, dtype=np.float64)
        if pose.shape != (3,):
            raise ValueError(f"pose must be (x, y, theta) of shape (3,), got shape {pose.shape}")
        return pose[None, :], [scan]


def _check_laser_scans(scans: Sequence) -> None:
    for s in scans:
        if not isinstance(s, LaserScan):
            raise TypeError(f"OccupancyMapper needs LaserScan objects, got {type(s).__name__}")


class OccupancyMapper(_RasterMapper):
    """Log-odds occupancy grid from lidar scans at known poses.

    Args:
        shape: ``(H, W)`` cells of the raster, row 0 = bottom.
        resolution_m: cell edge, metres.
        origin_xy_m: world ``(x, y)`` of the lower-left corner of cell ``(0, 0)``, metres.
        params: log-odds increments, see `OccupancyParams`.

    Example (a real robot's log)::

        mapper = OccupancyMapper((200, 300), 0.05, (-1.0, -1.0))
        mapper.update_many(slam_poses, laser_scans)
        grid = mapper.to_grid()
    """

    def __init__(
        self,
        shape: tuple[int, int],
        resolution_m: float,
        origin_xy_m=(0.0, 0.0),
        params: OccupancyParams | None = None,
    ) -> None:
        super().__init__(shape, resolution_m, origin_xy_m)
        self.params = params if params is not None else OccupancyParams()
        self._L = np.zeros(self._shape, np.float64)
        self._ended = np.zeros(self._shape, np.bool_)  # cells a return ended in (`clear_unobserved` stops there)
        self._blocked: np.ndarray | None = None  # `clear_unobserved`'s stopping cells, until the next update

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        state["_blocked"] = None  # derived: rebuilt on use
        return state

    def __setstate__(self, state: dict) -> None:
        state.setdefault("_ended", state["_L"] > 0.0)  # pickled before returns were recorded: the best guess
        state["_blocked"] = None
        self.__dict__.update(state)

    @classmethod
    def like(cls, grid: GridMap, params: OccupancyParams | None = None) -> OccupancyMapper:
        """An empty mapper on the raster of ``grid``."""
        return cls(grid.shape, grid.resolution_m, grid.origin_xy_m, params)

    def update(self, pose: np.ndarray, scan: LaserScan) -> None:
        """Integrate one lidar scan taken at ``pose`` ``(x, y, theta)`` (metres, radians)."""
        self.update_many(*self._one(pose, scan))

    def update_many(self, poses: np.ndarray, scans: Sequence[LaserScan]) -> None:
        """Integrate scans ``scans[i]`` taken at ``poses[i]`` (``(N, 3)``), in order, in one compiled pass."""
        _check_laser_scans(scans)
        self._integrate(self._beams(poses, scans, self.params.max_range_m))

    def update_arrays(self, poses: np.ndarray, ranges: np.ndarray, angles: np.ndarray, range_max_m: float) -> None:
        """`update_many` for scans held as arrays (no scan objects): ``ranges (N, B)`` metres taken at
        ``poses (N, 3)``, beam angles ``(B,)`` (or ``(N, B)``) in the robot frame, one ``range_max_m``."""
        self._integrate(self._beam_arrays(poses, ranges, angles, range_max_m, self.params.max_range_m))

    def clear_unobserved(self, poses: np.ndarray, scans: Sequence[LaserScan]) -> None:
        """A second pass over scans for a lidar whose dropouts read as no return (``clear_no_return=False``).

        Each no-return beam of ``scans[i]`` (taken at ``poses[i]``) walks out to its maximum range and stops
        at the first cell within one cell (8-neighbourhood) of a cell any return of the updates so far ended
        in; every cell it crosses before that gets log-odds at most ``l_free_unobserved`` (free). So a dropout
        in front of a surface stops at it and clears nothing behind it (also where the surface's cells ended
        up free-leaning, crossed by more beams than ended in them), while space that returns reach rarely or
        never (the middle of a hall more than twice the lidar's range across, where only the far ends of a few
        beams pass) is cleared by the beams that saw nothing there. Cells outside the raster are skipped until
        the beam enters it. Call it after the scans' updates, in as many chunks as memory needs (the pass
        adds no returns, so the order of chunks does not matter).
        """
        _check_laser_scans(scans)
        self._clear_unobserved(self._beams(poses, scans, self.params.max_range_m))

    def clear_unobserved_arrays(
        self, poses: np.ndarray, ranges: np.ndarray, angles: np.ndarray, range_max_m: float
    ) -> None:
        """`clear_unobserved` for scans held as arrays (as `update_arrays` takes them)."""
        self._clear_unobserved(self._beam_arrays(poses, ranges, angles, range_max_m, self.params.max_range_m))

    def _clear_unobserved(self, beams) -> None:
        if self._blocked is None:  # a cache: only updates add returns
            self._blocked = ndimage.maximum_filter(self._ended.view(np.uint8), size=3, mode="constant") > 0
        if beams is None or not beams[6].any():
            return
        u0, v0, du, dv, t_end, _, k = beams
        _no_return_kernel(self._L, self._blocked, u0[k], v0[k], du[k], dv[k], t_end[k], self.params.l_free_unobserved,
                          *_buffers(float(t_end[k].max())))  # fmt: skip

    def _integrate(self, beams) -> None:
        self._blocked = None
        if beams is None:
            return
        p = self.params
        if not p.clear_no_return:  # returns beyond max_range_m still clear
            beams = self._drop_no_return(beams)
            if beams is None:
                return
        u0, v0, du, dv, t_end, returned, _ = beams
        _occupancy_kernel(self._L, self._ended, u0, v0, du, dv, t_end, returned, p.l_free, p.l_occ, p.l_min, p.l_max,
                          *_buffers(float(t_end.max())))  # fmt: skip

    def to_grid(
        self,
        semantic: SemanticMapper | None = None,
        occupied_thresh: float = 0.65,
        free_thresh: float = 0.196,
        semantic_thresh: float = 0.5,
    ) -> GridMap:
        """The current map as a `GridMap` (unobserved cells ``0.5``).

        ``semantic`` (on the same raster, else ``ValueError``) supplies the class grids;
        without it the map has no classes. Thresholds are passed to the ``GridMap``.
        """
        if semantic is not None:
            return semantic.to_grid(self, occupied_thresh, free_thresh, semantic_thresh)
        return GridMap(
            occupancy=self.probabilities().astype(np.float32),
            resolution_m=self._res,
            origin_xy_m=self._origin,
            occupied_thresh=occupied_thresh,
            free_thresh=free_thresh,
            semantic_thresh=semantic_thresh,
        )


class SemanticMapper(_RasterMapper):
    """Per-class Bayesian (log-odds) semantic grids from semantic pseudo-laser scans at known poses.

    Args:
        shape: ``(H, W)`` cells of the raster, row 0 = bottom (as `OccupancyMapper`).
        resolution_m: cell edge, metres.
        origin_xy_m: world ``(x, y)`` of the lower-left corner of cell ``(0, 0)``, metres.
        class_names: class of label ``k + 1`` is ``class_names[k]``; default the paper's four.
        params: log-odds increments, see `SemanticParams`.

    Scans with a label greater than ``len(class_names)`` raise ``ValueError``.
    """

    def __init__(
        self,
        shape: tuple[int, int],
        resolution_m: float,
        origin_xy_m=(0.0, 0.0),
        class_names: Sequence[str] = DEFAULT_CLASS_NAMES,
        params: SemanticParams | None = None,
    ) -> None:
        super().__init__(shape, resolution_m, origin_xy_m)
        names = tuple(str(n) for n in class_names)
        if not names:
            raise ValueError("SemanticMapper needs at least one class")
        if len(set(names)) != len(names):
            raise ValueError(f"class_names must be unique, got {names}")
        self.class_names = names
        self.params = params if params is not None else SemanticParams()
        # classes innermost: a beam's cell update touches all C classes, so they share a cache line
        self._L = np.zeros(self._shape + (len(names),), np.float64)

    def _planes(self) -> np.ndarray:
        return np.moveaxis(self._L, -1, 0)

    @classmethod
    def like(
        cls, grid: GridMap, class_names: Sequence[str] | None = None, params: SemanticParams | None = None
    ) -> SemanticMapper:
        """An empty mapper on the raster of ``grid`` (classes: ``class_names`` or the grid's, else the default)."""
        names = class_names if class_names is not None else (grid.class_names or DEFAULT_CLASS_NAMES)
        return cls(grid.shape, grid.resolution_m, grid.origin_xy_m, names, params)

    def update(self, pose: np.ndarray, scan: SemanticScan) -> None:
        """Integrate one semantic scan taken at ``pose`` ``(x, y, theta)`` (metres, radians)."""
        self.update_many(*self._one(pose, scan))

    def update_many(self, poses: np.ndarray, scans: Sequence[SemanticScan]) -> None:
        """Integrate scans ``scans[i]`` taken at ``poses[i]`` (``(N, 3)``), in order, in one compiled pass."""
        n_cls = len(self.class_names)
        for s in scans:
            if not isinstance(s, SemanticScan):
                raise TypeError(f"SemanticMapper needs SemanticScan objects, got {type(s).__name__}")
            if s.labels.size and s.labels.max() > n_cls:
                raise ValueError(f"scan label {int(s.labels.max())} but the mapper has {n_cls} classes")
        labels = np.concatenate([s.labels for s in scans]).astype(np.int64)
        kept = self._beams(poses, scans, self.params.max_range_m, labels)
        if kept is None:
            return
        self._integrate(*kept)

    def update_arrays(
        self, poses: np.ndarray, ranges: np.ndarray, labels: np.ndarray, angles: np.ndarray, range_max_m: float
    ) -> None:
        """`update_many` for scans held as arrays: ``ranges`` and integer ``labels`` ``(N, B)``
        (0 = none, ``k + 1`` = class ``k``) at ``poses (N, 3)``, angles ``(B,)`` or ``(N, B)``."""
        lab = np.asarray(labels)
        if lab.shape != np.shape(ranges) or (lab.size and not is_int_dtype(lab.dtype)):
            raise ValueError(f"labels must be integers of the ranges' shape {np.shape(ranges)}, got {lab.shape}")
        if lab.size and (lab.min() < 0 or lab.max() > len(self.class_names)):
            raise ValueError(f"labels must be in 0..{len(self.class_names)}, got {int(lab.min())}..{int(lab.max())}")
        beams = self._beam_arrays(poses, ranges, angles, range_max_m, self.params.max_range_m)
        if beams is not None:
            self._integrate(beams, lab.astype(np.int64).ravel())

    def _integrate(self, beams, labels: np.ndarray) -> None:
        p = self.params
        if not p.clear_no_return:
            kept = self._drop_no_return(beams, labels)
            if kept is None:
                return
            beams, labels = kept[:-1], kept[-1]
        u0, v0, du, dv, t_end, returned, _ = beams
        end_label = np.where(returned, labels, -1).astype(np.int64)
        free_delta = np.where(labels > 0, p.l_free_inside, p.l_free_outside).astype(np.float64)
        _semantic_kernel(self._L, u0, v0, du, dv, t_end, end_label, free_delta, p.l_hit, p.l_other_hit,
                         p.l_unlabelled_end, p.l_min, p.l_max, *_buffers(float(t_end.max())))  # fmt: skip

    def to_grid(
        self,
        occupancy: OccupancyMapper | GridMap | None = None,
        occupied_thresh: float = 0.65,
        free_thresh: float = 0.196,
        semantic_thresh: float = 0.5,
    ) -> GridMap:
        """The semantic grids as a `GridMap`.

        ``occupancy`` (an `OccupancyMapper` or a ``GridMap`` on the same raster, else
        ``ValueError``) supplies the occupancy grid; without it every cell is unknown (0.5).
        """
        if occupancy is None:
            occ = np.full(self._shape, 0.5, np.float32)
        else:
            if not self._same_raster(occupancy):
                raise ValueError(
                    f"occupancy raster {tuple(occupancy.shape)} @ {occupancy.resolution_m} m from "
                    f"{tuple(occupancy.origin_xy_m)} differs from the semantic raster {self._shape} @ "
                    f"{self._res} m from {self._origin}"
                )
            occ = occupancy.occupancy if isinstance(occupancy, GridMap) else occupancy.probabilities()
        return GridMap(
            occupancy=np.asarray(occ, np.float32),
            resolution_m=self._res,
            origin_xy_m=self._origin,
            semantic=np.ascontiguousarray(expit(self._planes()), dtype=np.float32),
            class_names=self.class_names,
            occupied_thresh=occupied_thresh,
            free_thresh=free_thresh,
            semantic_thresh=semantic_thresh,
        )


def drop_unsupported_class_cells(grid: GridMap, support_p: float = 0.9, radius_m: float = 0.1) -> GridMap:
    """``grid`` without the class cells no confident cell of their class backs up.

    A class-``k`` cell (probability above ``grid.semantic_thresh``) stays if some class-``k`` cell
    within ``radius_m`` (Chebyshev distance, rounded to whole cells) has probability at least
    ``support_p``, itself included; the others get probability ``grid.semantic_thresh`` (no longer
    that class). The occupancy and every other field are ``grid``'s.

    Why: a detector that mislabels a whole object in one frame gives each surface cell it saw one hit
    of the wrong class (`SemanticParams.l_hit`: enough to mark it), and cells the drive saw rarely keep
    it. Such stray cells are few and isolated; an object's own cells are backed by confidently marked
    neighbours (docs/maps.md, "Stray class cells", has the counts).

    Raises:
        ValueError: ``support_p`` not in ``(grid.semantic_thresh, 1]`` or ``radius_m`` negative.
    """
    if not (is_real(support_p) and grid.semantic_thresh < support_p <= 1.0):
        raise ValueError(f"support_p must be in ({grid.semantic_thresh}, 1], got {support_p!r}")
    if not (is_real(radius_m) and math.isfinite(radius_m) and radius_m >= 0):
        raise ValueError(f"radius_m must be a number >= 0, got {radius_m!r}")
    if grid.semantic.shape[0] == 0:
        return grid
    r = min(int(round(radius_m / grid.resolution_m)), max(grid.shape))  # farther reaches every cell anyway
    sem = np.array(grid.semantic, dtype=np.float32)
    for k in range(sem.shape[0]):
        marked = sem[k] > grid.semantic_thresh
        strong = (sem[k] >= support_p).astype(np.uint8)
        backed = ndimage.maximum_filter(strong, size=2 * r + 1, mode="constant") > 0  # a square of side 2r+1 cells
        sem[k][marked & ~backed] = grid.semantic_thresh
    return dataclasses.replace(grid, semantic=sem)


def build_grid_map(
    shape: tuple[int, int],
    resolution_m: float,
    origin_xy_m,
    poses: np.ndarray,
    laser_scans: Sequence[LaserScan],
    semantic_poses: np.ndarray | None = None,
    semantic_scans: Sequence[SemanticScan] = (),
    class_names: Sequence[str] = DEFAULT_CLASS_NAMES,
    occupancy_params: OccupancyParams | None = None,
    semantic_params: SemanticParams | None = None,
) -> GridMap:
    """One-call mapping run: occupancy from ``laser_scans`` at ``poses``, semantics from
    ``semantic_scans`` at ``semantic_poses`` (default ``poses``), on one raster.

    With no semantic scans the map still carries ``class_names`` (all cells at 0.5).
    """
    occ = OccupancyMapper(shape, resolution_m, origin_xy_m, occupancy_params)
    occ.update_many(poses, laser_scans)
    sem = SemanticMapper(shape, resolution_m, origin_xy_m, class_names, semantic_params)
    if len(semantic_scans):
        sem.update_many(poses if semantic_poses is None else semantic_poses, semantic_scans)
    return sem.to_grid(occ)
