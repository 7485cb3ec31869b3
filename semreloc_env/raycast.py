"""Vectorised ray casting against line segments: the geometry pymunk collides with.

The world hands its static segments (wall segments and object polygon edges,
read back from the pymunk shapes) to :class:`SegmentScene`; every sensor casts
against that one scene, so lidar, camera and collisions cannot drift apart.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


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
        a = np.ascontiguousarray(self.segments[:, 0], dtype=np.float64)
        e = np.ascontiguousarray(self.segments[:, 1] - self.segments[:, 0], dtype=np.float64)
        object.__setattr__(self, "_a", a)
        object.__setattr__(self, "_e", e)

    def cast(self, origin: np.ndarray, angles: np.ndarray, max_range: float) -> tuple[np.ndarray, np.ndarray]:
        """Cast rays from ``origin`` ``(2,)`` at world-frame ``angles`` ``(B,)`` radians.

        Returns:
            ``ranges`` ``(B,)``: distance to the first segment hit, ``max_range`` if none
            within range; ``hit`` ``(B,)`` int64: index of the segment hit, ``-1`` if none.
        """
        d = np.stack([np.cos(angles), np.sin(angles)], axis=1)  # (B, 2)
        ao = self._a - np.asarray(origin, dtype=np.float64)  # (M, 2)
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
        """Indices of the segments within ``reach_m`` of ``point`` ``(2,)``, ascending."""
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
