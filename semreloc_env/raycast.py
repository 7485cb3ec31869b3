"""Ray casting against line segments: the geometry pymunk collides with.

The world hands its static segments (wall segments and object polygon edges,
read back from the pymunk shapes) to `SegmentScene`; every sensor casts
against that one scene, so lidar, camera and collisions cannot drift apart.

Two implementations of the same intersection test:

* `SegmentScene.cast` / `SegmentScene.cast_many` — compiled (numba): each ray walks
  a uniform grid of segment buckets and tests only the segments of the cells it crosses, so a
  scan in a large layout costs about as much as one in a small layout. Used by the sensors.
* `SegmentScene.cast_reference` — the plain NumPy ``(B, M)`` broadcast, kept as the
  reference the compiled path is tested against (same formulas, same tie-breaking).

Both use, for ray ``o + t d`` and segment ``a + s e``: ``denom = cross(d, e)``,
``t = cross(a - o, e) / denom``, ``s = cross(a - o, d) / denom``; a hit needs
``|denom| > 1e-12``, ``t >= 0`` and ``-1e-12 <= s <= 1 + 1e-12``; the first segment (lowest
index) with the smallest ``t`` wins.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from filters.pose import cos_sin

_PAD_M = 1e-6
"""Segments are listed in every bucket cell they pass within this distance of (round-off margin)."""
_MAX_BUCKETS_PER_SIDE = 2048
"""At most this many bucket cells along either side of a `SegmentScene` (~4 M cells, 34 MB)."""


@numba.njit(cache=True, nogil=True)
def _build_buckets(a, e, gx0, gy0, cell, nx, ny):  # pragma: no cover - compiled
    """CSR ``(start (nx*ny+1,), items)`` of the segments passing within ``_PAD_M`` of each grid cell."""
    m = a.shape[0]
    half_diag = 0.5 * cell * math.sqrt(2.0) + _PAD_M
    counts = np.zeros(nx * ny + 1, np.int64)
    for pass_ in range(2):
        if pass_ == 1:
            for k in range(nx * ny):
                counts[k + 1] += counts[k]
            items = np.empty(counts[nx * ny], np.int64)
            fill = counts[:-1].copy()
        for i in range(m):
            x0 = min(a[i, 0], a[i, 0] + e[i, 0])
            x1 = max(a[i, 0], a[i, 0] + e[i, 0])
            y0 = min(a[i, 1], a[i, 1] + e[i, 1])
            y1 = max(a[i, 1], a[i, 1] + e[i, 1])
            c0 = max(0, int(math.floor((x0 - _PAD_M - gx0) / cell)))
            c1 = min(nx - 1, int(math.floor((x1 + _PAD_M - gx0) / cell)))
            r0 = max(0, int(math.floor((y0 - _PAD_M - gy0) / cell)))
            r1 = min(ny - 1, int(math.floor((y1 + _PAD_M - gy0) / cell)))
            ee = max(e[i, 0] * e[i, 0] + e[i, 1] * e[i, 1], 1e-18)
            for r in range(r0, r1 + 1):
                for c in range(c0, c1 + 1):
                    px = gx0 + (c + 0.5) * cell
                    py = gy0 + (r + 0.5) * cell
                    t = min(max(((px - a[i, 0]) * e[i, 0] + (py - a[i, 1]) * e[i, 1]) / ee, 0.0), 1.0)
                    dx = a[i, 0] + t * e[i, 0] - px
                    dy = a[i, 1] + t * e[i, 1] - py
                    if dx * dx + dy * dy <= half_diag * half_diag:  # conservative: may list a few extra
                        if pass_ == 0:
                            counts[r * nx + c + 1] += 1
                        else:
                            items[fill[r * nx + c]] = i
                            fill[r * nx + c] += 1
    return counts, items


@numba.njit(cache=True, nogil=True)
def _cast_kernel(ox, oy, cos_a, sin_a, a, e, start, items, gx0, gy0, cell, nx, ny, max_range, out_r, out_hit):
    """Rays ``(R, B)`` from origins ``(R,)`` against segments ``a, e (M, 2)``; writes ``out_r, out_hit (R, B)``.

    Walks each ray through a uniform grid of segment buckets (Amanatides & Woo), testing the
    segments listed in each cell it crosses, and stops once the best hit lies before the
    cell's exit: the same first hit (lowest index among equal ``t``) as testing every segment.
    """  # pragma: no cover - compiled
    n_rob, n_beam = cos_a.shape
    gx1 = gx0 + nx * cell
    gy1 = gy0 + ny * cell
    for r in range(n_rob):
        px = ox[r]
        py = oy[r]
        for b in range(n_beam):
            dxr = cos_a[r, b]
            dyr = sin_a[r, b]
            best = np.inf
            hit = -1
            # clip the ray to the grid box
            t0 = 0.0
            t1 = max_range
            if dxr != 0.0:
                ta = (gx0 - px) / dxr
                tb = (gx1 - px) / dxr
                t0 = max(t0, min(ta, tb))
                t1 = min(t1, max(ta, tb))
            elif px < gx0 or px > gx1:
                t1 = -1.0
            if dyr != 0.0:
                ta = (gy0 - py) / dyr
                tb = (gy1 - py) / dyr
                t0 = max(t0, min(ta, tb))
                t1 = min(t1, max(ta, tb))
            elif py < gy0 or py > gy1:
                t1 = -1.0
            if t0 <= t1:
                cx = min(max(int(math.floor((px + t0 * dxr - gx0) / cell)), 0), nx - 1)
                cy = min(max(int(math.floor((py + t0 * dyr - gy0) / cell)), 0), ny - 1)
                sx = 1 if dxr > 0.0 else -1
                sy = 1 if dyr > 0.0 else -1
                if dxr != 0.0:
                    t_next_x = (gx0 + (cx + (1 if dxr > 0.0 else 0)) * cell - px) / dxr
                    dt_x = cell / abs(dxr)
                else:
                    t_next_x = np.inf
                    dt_x = np.inf
                if dyr != 0.0:
                    t_next_y = (gy0 + (cy + (1 if dyr > 0.0 else 0)) * cell - py) / dyr
                    dt_y = cell / abs(dyr)
                else:
                    t_next_y = np.inf
                    dt_y = np.inf
                while True:
                    k = cy * nx + cx
                    for q in range(start[k], start[k + 1]):
                        i = items[q]
                        ex = e[i, 0]
                        ey = e[i, 1]
                        aox = a[i, 0] - px
                        aoy = a[i, 1] - py
                        denom = dxr * ey - dyr * ex
                        if not abs(denom) > 1e-12:
                            continue
                        t = (aox * ey - aoy * ex) / denom
                        s = (aox * dyr - aoy * dxr) / denom
                        if t >= 0.0 and s >= -1e-12 and s <= 1.0 + 1e-12 and (t < best or (t == best and i < hit)):
                            best = t
                            hit = i
                    t_exit = min(t_next_x, t_next_y)
                    if best < t_exit or t_exit > t1:
                        break
                    if t_next_x < t_next_y:
                        cx += sx
                        t_next_x += dt_x
                        if cx < 0 or cx >= nx:
                            break
                    else:
                        cy += sy
                        t_next_y += dt_y
                        if cy < 0 or cy >= ny:
                            break
            if best < max_range:
                out_r[r, b] = best
                out_hit[r, b] = hit
            else:
                out_r[r, b] = max_range
                out_hit[r, b] = -1
    return 0


@numba.njit(cache=True, nogil=True)
def _near_kernel(px, py, reach, a, e, start, items, gx0, gy0, cell, nx, ny, seen):  # pragma: no cover - compiled
    """Mark ``seen[i]`` for the segments within ``reach`` of ``(px, py)`` (the formula of ``distances``).

    Returns how many were marked."""
    c0 = max(0, int(math.floor((px - reach - gx0) / cell)))
    c1 = min(nx - 1, int(math.floor((px + reach - gx0) / cell)))
    r0 = max(0, int(math.floor((py - reach - gy0) / cell)))
    r1 = min(ny - 1, int(math.floor((py + reach - gy0) / cell)))
    count = 0
    for r in range(r0, r1 + 1):
        for c in range(c0, c1 + 1):
            k = r * nx + c
            for q in range(start[k], start[k + 1]):
                i = items[q]
                if seen[i]:
                    continue
                ex = e[i, 0]
                ey = e[i, 1]
                ee = max(ex * ex + ey * ey, 1e-18)
                t = min(max(((px - a[i, 0]) * ex + (py - a[i, 1]) * ey) / ee, 0.0), 1.0)
                dx = a[i, 0] + t * ex - px
                dy = a[i, 1] + t * ey - py
                if math.sqrt(dx * dx + dy * dy) <= reach:
                    seen[i] = True
                    count += 1
    return count


@dataclass(frozen=True, eq=False)
class SegmentScene:
    """Static line segments with the object each belongs to.

    Attributes:
        segments: ``(M, 2, 2)`` float64 endpoints in metres.
        owner: ``(M,)`` int64, index of the layout object a segment bounds, ``-1`` for walls.
    """

    segments: np.ndarray
    owner: np.ndarray

    cell_m: float = 1.0
    """Edge of the bucket grid the compiled caster walks, metres."""

    def __post_init__(self) -> None:
        seg = np.asarray(self.segments, dtype=np.float64).reshape(-1, 2, 2)
        if not (np.isfinite(self.cell_m) and self.cell_m > 0):
            raise ValueError(f"cell_m must be a positive number, got {self.cell_m!r}")
        a = np.ascontiguousarray(seg[:, 0])
        e = np.ascontiguousarray(seg[:, 1] - seg[:, 0])
        object.__setattr__(self, "_a", a)
        object.__setattr__(self, "_e", e)
        if len(seg):
            lo = seg.reshape(-1, 2).min(axis=0) - 2 * _PAD_M
            hi = seg.reshape(-1, 2).max(axis=0) + 2 * _PAD_M
        else:
            lo, hi = np.zeros(2), np.ones(2)
        # buckets of cell_m, coarser where a layout is so large that the grid would pass
        # _MAX_BUCKETS_PER_SIDE per side (a bucket grid is an index: it changes no result)
        cell = max(float(self.cell_m), float(np.max(hi - lo)) / _MAX_BUCKETS_PER_SIDE)
        nx, ny = (max(1, int(np.ceil(v))) for v in (hi - lo) / cell)
        start, items = _build_buckets(a, e, float(lo[0]), float(lo[1]), cell, nx, ny)
        object.__setattr__(self, "_grid", (start, items, float(lo[0]), float(lo[1]), cell, nx, ny))

    @property
    def bucket_grid(self) -> tuple:
        """``(start, items, x0, y0, cell_m, nx, ny)``: CSR of the segments near each cell of the bucket grid
        (every segment passing within 1e-6 m of a cell is listed in it; cell ``(row, col)`` is ``row * nx + col``)."""
        return self._grid

    def cast(self, origin: np.ndarray, angles: np.ndarray, max_range: float) -> tuple[np.ndarray, np.ndarray]:
        """Cast rays from ``origin`` ``(2,)`` at world-frame ``angles`` ``(B,)`` radians.

        Returns:
            ``ranges`` ``(B,)``: distance to the first segment hit, ``max_range`` if none
            within range; ``hit`` ``(B,)`` int64: index of the segment hit, ``-1`` if none.

        The numbers of `cast_many` for the one origin, without its shape checks where the shapes are these.
        """
        o = np.asarray(origin, dtype=np.float64)
        ang = np.asarray(angles, dtype=np.float64)
        if o.shape != (2,) or ang.ndim != 1:  # cast_many checks the shapes
            ranges, hit = self.cast_many(o[None, :2], ang[None, :], max_range)
            return ranges[0], hit[0]
        ranges, hit = self._cast(o[:1], o[1:], ang[None, :], max_range)
        return ranges[0], hit[0]

    def cast_many(self, origins: np.ndarray, angles: np.ndarray, max_range: float) -> tuple[np.ndarray, np.ndarray]:
        """`cast` for ``R`` origins ``(R, 2)`` at once, angles ``(R, B)``; returns ``(R, B)`` arrays."""
        o = np.asarray(origins, dtype=np.float64)
        ang = np.asarray(angles, dtype=np.float64)
        if o.ndim != 2 or o.shape[1] != 2 or ang.ndim != 2 or ang.shape[0] != o.shape[0]:
            raise ValueError(f"origins must be (R, 2) and angles (R, B), got {o.shape} and {ang.shape}")
        return self._cast(np.ascontiguousarray(o[:, 0]), np.ascontiguousarray(o[:, 1]), ang, max_range)

    def _cast(self, ox: np.ndarray, oy: np.ndarray, ang: np.ndarray, max_range: float) -> tuple[np.ndarray, np.ndarray]:
        """The compiled cast of checked, contiguous origins ``ox, oy`` ``(R,)`` at float64 angles ``(R, B)``; their cos
        and sin from `filters.pose.cos_sin`, NumPy's (which, unlike NumPy, does not warn for an infinite angle)."""
        c, s = cos_sin(ang.reshape(-1))
        out_r = np.empty(ang.shape)
        out_hit = np.empty(ang.shape, np.int64)
        _cast_kernel(
            ox, oy, c.reshape(ang.shape), s.reshape(ang.shape), self._a, self._e, *self._grid, float(max_range), out_r,
            out_hit,
        )  # fmt: skip
        return out_r, out_hit

    def cast_reference(self, origin: np.ndarray, angles: np.ndarray, max_range: float) -> tuple[np.ndarray, np.ndarray]:
        """`cast` as plain NumPy broadcasting over ``(B, M)`` (the reference; slower)."""
        angles = np.asarray(angles, dtype=np.float64)
        d = np.stack([np.cos(angles), np.sin(angles)], axis=1)  # (B, 2)
        ao = self._a - np.asarray(origin, dtype=np.float64)[:2]  # (M, 2)
        e = self._e
        denom = d[:, None, 0] * e[None, :, 1] - d[:, None, 1] * e[None, :, 0]  # cross(d, e)
        num_t = ao[None, :, 0] * e[None, :, 1] - ao[None, :, 1] * e[None, :, 0]  # cross(a-o, e)
        num_s = ao[None, :, 0] * d[:, None, 1] - ao[None, :, 1] * d[:, None, 0]  # cross(a-o, d)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = num_t / denom
            s = num_s / denom
        ok = (np.abs(denom) > 1e-12) & (t >= 0.0) & (s >= -1e-12) & (s <= 1.0 + 1e-12)
        t = np.where(ok, t, np.inf)
        hit = np.argmin(t, axis=1)
        ranges = t[np.arange(len(angles)), hit]
        none = ~(ranges < max_range)
        ranges = np.where(none, max_range, ranges)
        return ranges, np.where(none, -1, hit).astype(np.int64)

    @property
    def a(self) -> np.ndarray:
        """``(M, 2)`` first end point of every segment."""
        return self._a

    @property
    def e(self) -> np.ndarray:
        """``(M, 2)`` vector from the first to the second end point."""
        return self._e

    def near(self, point: np.ndarray, reach_m: float) -> np.ndarray:
        """Indices of the segments within ``reach_m`` of ``point`` ``(2,)``, ascending (compiled:
        only the bucket cells within ``reach_m`` are looked at; `near_reference` tests all)."""
        start, items, gx0, gy0, cell, nx, ny = self._grid
        p = np.asarray(point, dtype=np.float64)
        seen = np.zeros(self._a.shape[0], dtype=np.bool_)
        n = _near_kernel(
            float(p[0]), float(p[1]), float(reach_m), self._a, self._e, start, items, gx0, gy0, cell, nx, ny, seen
        )
        return np.flatnonzero(seen) if n else np.zeros(0, np.int64)

    def near_reference(self, point: np.ndarray, reach_m: float) -> np.ndarray:
        """`near` by the distance to every segment (NumPy)."""
        return np.flatnonzero(self.distance_to(point) <= reach_m)

    def distance_to(self, point: np.ndarray) -> np.ndarray:
        """``(M,)`` Euclidean distances from ``point`` ``(2,)`` to every segment."""
        return self.distances(np.asarray(point, dtype=np.float64)[None])[0]

    def distances(self, points: np.ndarray) -> np.ndarray:
        """``(P, M)`` Euclidean distances from ``points`` ``(P, 2)`` to every segment."""
        p = np.asarray(points, dtype=np.float64)[:, None, :]
        ee = np.maximum(np.sum(self._e * self._e, axis=1), 1e-18)
        t = np.clip(np.sum((p - self._a) * self._e, axis=-1) / ee, 0.0, 1.0)
        return np.linalg.norm(self._a + t[..., None] * self._e - p, axis=-1)
