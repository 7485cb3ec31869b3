"""Ray casting against line segments: the geometry pymunk collides with.

The world hands its static segments (wall segments and object polygon edges,
read back from the pymunk shapes) to :class:`SegmentScene`; every sensor casts
against that one scene, so lidar, camera and collisions cannot drift apart.

Two implementations of the same intersection test:

* :meth:`SegmentScene.cast` / :meth:`SegmentScene.cast_many` — a compiled (numba) loop over
  rays and segments, skipping segments whose bounding box lies beyond the range limit, so
  a scan in a large layout costs about as much as one in a small layout. Used by the sensors.
* :meth:`SegmentScene.cast_reference` — the plain NumPy ``(B, M)`` broadcast, kept as the
  reference the compiled path is tested against (same formulas, same tie-breaking).

Both use, for ray ``o + t d`` and segment ``a + s e``: ``denom = cross(d, e)``,
``t = cross(a - o, e) / denom``, ``s = cross(a - o, d) / denom``; a hit needs
``|denom| > 1e-12``, ``t >= 0`` and ``-1e-12 <= s <= 1 + 1e-12``; the first segment (lowest
index) with the smallest ``t`` wins.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np


@numba.njit(cache=True, nogil=True)
def _cast_kernel(ox, oy, cos_a, sin_a, a, e, max_range, out_r, out_hit):  # pragma: no cover - compiled
    """Rays ``(R, B)`` from origins ``(R,)`` against segments ``a, e (M, 2)``; writes ``out_r, out_hit (R, B)``."""
    n_rob, n_beam = cos_a.shape
    m = a.shape[0]
    near = np.empty(m, np.int64)
    for r in range(n_rob):
        px = ox[r]
        py = oy[r]
        # segments whose bounding box is within max_range of the origin (others cannot be hit in range)
        k = 0
        for i in range(m):
            x0 = a[i, 0]
            x1 = a[i, 0] + e[i, 0]
            y0 = a[i, 1]
            y1 = a[i, 1] + e[i, 1]
            lo_x = min(x0, x1)
            hi_x = max(x0, x1)
            lo_y = min(y0, y1)
            hi_y = max(y0, y1)
            dx = lo_x - px if px < lo_x else (px - hi_x if px > hi_x else 0.0)
            dy = lo_y - py if py < lo_y else (py - hi_y if py > hi_y else 0.0)
            if dx * dx + dy * dy <= max_range * max_range:
                near[k] = i
                k += 1
        for b in range(n_beam):
            dxr = cos_a[r, b]
            dyr = sin_a[r, b]
            best = np.inf
            hit = -1
            for q in range(k):
                i = near[q]
                ex = e[i, 0]
                ey = e[i, 1]
                aox = a[i, 0] - px
                aoy = a[i, 1] - py
                denom = dxr * ey - dyr * ex
                if not abs(denom) > 1e-12:
                    continue
                t = (aox * ey - aoy * ex) / denom
                s = (aox * dyr - aoy * dxr) / denom
                if t >= 0.0 and s >= -1e-12 and s <= 1.0 + 1e-12 and t < best:
                    best = t
                    hit = i
            if best < max_range:
                out_r[r, b] = best
                out_hit[r, b] = hit
            else:
                out_r[r, b] = max_range
                out_hit[r, b] = -1
    return 0


@dataclass(frozen=True, eq=False)
class SegmentScene:
    """Static line segments with the object each belongs to.

    Attributes:
        segments: ``(M, 2, 2)`` float64 endpoints in metres.
        owner: ``(M,)`` int64, index of the layout object a segment bounds, ``-1`` for walls.
    """

    segments: np.ndarray
    owner: np.ndarray

    def __post_init__(self) -> None:
        seg = np.asarray(self.segments, dtype=np.float64).reshape(-1, 2, 2)
        a = np.ascontiguousarray(seg[:, 0])
        e = np.ascontiguousarray(seg[:, 1] - seg[:, 0])
        object.__setattr__(self, "_a", a)
        object.__setattr__(self, "_e", e)

    def cast(self, origin: np.ndarray, angles: np.ndarray, max_range: float) -> tuple[np.ndarray, np.ndarray]:
        """Cast rays from ``origin`` ``(2,)`` at world-frame ``angles`` ``(B,)`` radians.

        Returns:
            ``ranges`` ``(B,)``: distance to the first segment hit, ``max_range`` if none
            within range; ``hit`` ``(B,)`` int64: index of the segment hit, ``-1`` if none.
        """
        o = np.asarray(origin, dtype=np.float64)
        ranges, hit = self.cast_many(o[None, :2], np.asarray(angles, dtype=np.float64)[None, :], max_range)
        return ranges[0], hit[0]

    def cast_many(self, origins: np.ndarray, angles: np.ndarray, max_range: float) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`cast` for ``R`` origins ``(R, 2)`` at once, angles ``(R, B)``; returns ``(R, B)`` arrays."""
        o = np.asarray(origins, dtype=np.float64)
        ang = np.asarray(angles, dtype=np.float64)
        if o.ndim != 2 or o.shape[1] != 2 or ang.ndim != 2 or ang.shape[0] != o.shape[0]:
            raise ValueError(f"origins must be (R, 2) and angles (R, B), got {o.shape} and {ang.shape}")
        out_r = np.empty(ang.shape)
        out_hit = np.empty(ang.shape, np.int64)
        _cast_kernel(
            np.ascontiguousarray(o[:, 0]),
            np.ascontiguousarray(o[:, 1]),
            np.cos(ang),
            np.sin(ang),
            self._a,
            self._e,
            float(max_range),
            out_r,
            out_hit,
        )
        return out_r, out_hit

    def cast_reference(self, origin: np.ndarray, angles: np.ndarray, max_range: float) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`cast` as plain NumPy broadcasting over ``(B, M)`` (the reference; slower)."""
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

    def distance_to(self, point: np.ndarray) -> np.ndarray:
        """``(M,)`` Euclidean distances from ``point`` ``(2,)`` to every segment."""
        return self.distances(np.asarray(point, dtype=np.float64)[None])[0]

    def distances(self, points: np.ndarray) -> np.ndarray:
        """``(P, M)`` Euclidean distances from ``points`` ``(P, 2)`` to every segment."""
        p = np.asarray(points, dtype=np.float64)[:, None, :]
        ee = np.maximum(np.sum(self._e * self._e, axis=1), 1e-18)
        t = np.clip(np.sum((p - self._a) * self._e, axis=-1) / ee, 0.0, 1.0)
        return np.linalg.norm(self._a + t[..., None] * self._e - p, axis=-1)
