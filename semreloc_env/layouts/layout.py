"""Layouts: the geometry of a world as plain, validated data.

A layout is the single source of truth for one environment: it builds the pymunk
space (physics and true sensing, :mod:`semreloc_env.world`) and rasterises to the
grids a perfect map would hold (:mod:`semreloc_env.rasterize`).

File / dict format (JSON or YAML), all lengths in metres::

    name: lab                      # optional
    outer: [[0, 0], [15, 0], [15, 10], [0, 10]]   # closed outer wall polygon
    walls:                         # interior walls: open polylines, >= 2 points
      - [[5, 0], [5, 4]]
    objects:                       # semantic objects, each one of the classes below
      - {class: chair, polygon: [[1, 1], [1.5, 1], [1.5, 1.5], [1, 1.5]]}
      - {class: cabinet, center: [3, 0.3], size: [1.0, 0.5], angle_rad: 0.0}  # box shorthand

Classes: ``door``, ``chair``, ``trash_bin``, ``cabinet`` (paper 004).
Every problem found raises :class:`LayoutError` naming the offending entry.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from filters.mapping.grid import DEFAULT_CLASS_NAMES

CLASS_NAMES: tuple[str, ...] = DEFAULT_CLASS_NAMES
"""Object classes a layout may use; scan label ``k + 1`` is ``CLASS_NAMES[k]``."""

Point = tuple[float, float]


class LayoutError(ValueError):
    """A layout is malformed; the message names the offending entry."""


@dataclass(frozen=True)
class SemanticObject:
    """One object of a known class: a simple polygon, vertices counter-clockwise, metres."""

    cls: str
    polygon: tuple[Point, ...]
    name: str = ""

    @property
    def label(self) -> int:
        """The scan label of this object's class (``CLASS_NAMES.index(cls) + 1``)."""
        return CLASS_NAMES.index(self.cls) + 1

    def centroid(self) -> np.ndarray:
        """Area centroid ``(2,)`` in metres."""
        p = np.asarray(self.polygon)
        x, y = p[:, 0], p[:, 1]
        xn, yn = np.roll(x, -1), np.roll(y, -1)
        cross = x * yn - xn * y
        a = cross.sum() / 2.0
        return np.array([((x + xn) * cross).sum(), ((y + yn) * cross).sum()]) / (6.0 * a)


@dataclass(frozen=True)
class Layout:
    """Walls and semantic objects of a 2D world, in metres.

    Attributes:
        name: a label for plots and logs.
        outer: the closed outer wall polygon (counter-clockwise); the robot lives inside it.
        walls: interior walls, each an open polyline of >= 2 points.
        objects: the semantic objects.
    """

    name: str
    outer: tuple[Point, ...]
    walls: tuple[tuple[Point, ...], ...]
    objects: tuple[SemanticObject, ...]

    def wall_segments(self) -> np.ndarray:
        """``(M, 2, 2)`` float64: every wall segment (outer ring and interior polylines)."""
        segs = [_ring_segments(self.outer)]
        for wall in self.walls:
            w = np.asarray(wall, dtype=np.float64)
            segs.append(np.stack([w[:-1], w[1:]], axis=1))
        return np.concatenate(segs, axis=0)

    def object_segments(self) -> tuple[np.ndarray, np.ndarray]:
        """``(K, 2, 2)`` object edge segments and ``(K,)`` int index of the object each belongs to."""
        if not self.objects:
            return np.zeros((0, 2, 2)), np.zeros(0, np.int64)
        segs = [_ring_segments(o.polygon) for o in self.objects]
        owner = np.concatenate([np.full(len(s), i) for i, s in enumerate(segs)])
        return np.concatenate(segs, axis=0), owner.astype(np.int64)

    def bounds(self) -> tuple[float, float, float, float]:
        """``(x_min, x_max, y_min, y_max)`` of the outer wall."""
        p = np.asarray(self.outer)
        return float(p[:, 0].min()), float(p[:, 0].max()), float(p[:, 1].min()), float(p[:, 1].max())

    def to_dict(self) -> dict:
        """The plain-dict form accepted by :func:`layout_from_dict` (round-trips)."""
        return {
            "name": self.name,
            "outer": [list(p) for p in self.outer],
            "walls": [[list(p) for p in w] for w in self.walls],
            "objects": [
                {"class": o.cls, "name": o.name, "polygon": [list(p) for p in o.polygon]} for o in self.objects
            ],
        }


# --------------------------------------------------------------------------- geometry
def _ring_segments(ring: Sequence[Point]) -> np.ndarray:
    p = np.asarray(ring, dtype=np.float64)
    return np.stack([p, np.roll(p, -1, axis=0)], axis=1)


def _signed_area(p: np.ndarray) -> float:
    x, y = p[:, 0], p[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def _segments_cross(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray) -> bool:
    """True if closed segments ab and cd share a point."""

    def orient(p, q, r):
        v = (q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0])
        return 0 if abs(v) < 1e-12 else (1 if v > 0 else -1)

    def on_seg(p, q, r):
        return (
            min(p[0], r[0]) - 1e-12 <= q[0] <= max(p[0], r[0]) + 1e-12
            and min(p[1], r[1]) - 1e-12 <= q[1] <= max(p[1], r[1]) + 1e-12
        )

    o1, o2, o3, o4 = orient(a, b, c), orient(a, b, d), orient(c, d, a), orient(c, d, b)
    if o1 != o2 and o3 != o4:
        return True
    return (
        (o1 == 0 and on_seg(a, c, b))
        or (o2 == 0 and on_seg(a, d, b))
        or (o3 == 0 and on_seg(c, a, d))
        or (o4 == 0 and on_seg(c, b, d))
    )


def _check_simple_polygon(p: np.ndarray, what: str) -> None:
    n = len(p)
    if n < 3:
        raise LayoutError(f"{what}: a polygon needs at least 3 distinct vertices, got {n}")
    for i in range(n):
        for j in range(i + 1, n):
            if j == i + 1 or (i == 0 and j == n - 1):
                continue
            if _segments_cross(p[i], p[(i + 1) % n], p[j], p[(j + 1) % n]):
                raise LayoutError(f"{what}: polygon is self-intersecting (edges {i} and {j} cross)")
    if abs(_signed_area(p)) < 1e-9:
        raise LayoutError(f"{what}: polygon has zero area")


def point_in_polygon(pts: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Even-odd test: bool ``(P,)`` for points ``(P, 2)`` inside ``poly`` ``(V, 2)``."""
    pts = np.atleast_2d(np.asarray(pts, dtype=np.float64))
    x, y = pts[:, 0:1], pts[:, 1:2]
    x0, y0 = poly[:, 0][None, :], poly[:, 1][None, :]
    x1, y1 = np.roll(poly[:, 0], -1)[None, :], np.roll(poly[:, 1], -1)[None, :]
    straddle = (y0 > y) != (y1 > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        xc = x0 + (y - y0) * (x1 - x0) / (y1 - y0)
    return np.sum(straddle & (x < xc), axis=1) % 2 == 1


def _dist_points_to_ring(pts: np.ndarray, ring: np.ndarray) -> np.ndarray:
    a = ring[None, :, :]
    b = np.roll(ring, -1, axis=0)[None, :, :]
    p = pts[:, None, :]
    ab = b - a
    t = np.clip(np.sum((p - a) * ab, axis=-1) / np.maximum(np.sum(ab * ab, axis=-1), 1e-18), 0, 1)
    return np.min(np.linalg.norm(p - (a + t[..., None] * ab), axis=-1), axis=1)


# --------------------------------------------------------------------------- parsing
def _points(raw, what: str, min_points: int) -> np.ndarray:
    try:
        p = np.asarray(raw, dtype=np.float64)
    except (TypeError, ValueError):
        raise LayoutError(f"{what}: expected a list of [x, y] points, got {raw!r:.80}") from None
    if p.ndim != 2 or p.shape[1] != 2:
        raise LayoutError(f"{what}: expected a list of [x, y] points, got shape {p.shape}")
    if not np.all(np.isfinite(p)):
        raise LayoutError(f"{what}: coordinates must be finite numbers (found NaN or inf)")
    if len(p) < min_points:
        raise LayoutError(f"{what}: needs at least {min_points} points, got {len(p)}")
    return p


def _ring(raw, what: str) -> np.ndarray:
    p = _points(raw, what, 3)
    if len(p) > 3 and np.allclose(p[0], p[-1]):
        p = p[:-1]  # an explicitly closed ring repeats its first vertex
    keep = np.ones(len(p), bool)
    keep[1:] = np.any(np.abs(np.diff(p, axis=0)) > 1e-12, axis=1)
    p = p[keep]
    _check_simple_polygon(p, what)
    return p if _signed_area(p) > 0 else p[::-1]


def _box(entry: Mapping, what: str) -> np.ndarray:
    c = _points([entry["center"]], f"{what}.center", 1)[0]
    size = _points([entry["size"]], f"{what}.size", 1)[0]
    if np.any(size <= 0):
        raise LayoutError(f"{what}.size must be positive, got {size.tolist()}")
    ang = float(entry.get("angle_rad", 0.0))
    if not math.isfinite(ang):
        raise LayoutError(f"{what}.angle_rad must be finite")
    hx, hy = size / 2
    local = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
    rot = np.array([[math.cos(ang), -math.sin(ang)], [math.sin(ang), math.cos(ang)]])
    return local @ rot.T + c


_TOP_KEYS = {"name", "outer", "walls", "objects"}
_OBJECT_KEYS = {"class", "name", "polygon", "center", "size", "angle_rad"}


def layout_from_dict(data: Mapping, default_name: str = "layout") -> Layout:
    """Validate a plain dict (see the module docstring) and build a :class:`Layout`.

    Raises:
        LayoutError: unknown keys, malformed or non-finite coordinates, open,
            degenerate or self-intersecting polygons, unknown class names, or
            objects outside the outer wall. The message names the entry.
    """
    if not isinstance(data, Mapping):
        raise LayoutError(f"a layout must be a mapping, got {type(data).__name__}")
    unknown = set(data) - _TOP_KEYS
    if unknown:
        raise LayoutError(f"unknown layout keys {sorted(unknown)}; allowed: {sorted(_TOP_KEYS)}")
    if "outer" not in data:
        raise LayoutError("layout has no 'outer' wall polygon")
    name = str(data.get("name", default_name))
    outer = _ring(data["outer"], "outer")
    walls = []
    raw_walls = data.get("walls", []) or []
    if not isinstance(raw_walls, Sequence) or isinstance(raw_walls, str):
        raise LayoutError("'walls' must be a list of polylines")
    for i, w in enumerate(raw_walls):
        p = _points(w, f"walls[{i}]", 2)
        if np.any(np.linalg.norm(np.diff(p, axis=0), axis=1) < 1e-9):
            raise LayoutError(f"walls[{i}]: repeated consecutive point (zero-length segment)")
        inside = point_in_polygon(p, outer) | (_dist_points_to_ring(p, outer) < 1e-6)
        if not np.all(inside):
            raise LayoutError(f"walls[{i}]: point {p[~inside][0].tolist()} lies outside the outer wall")
        walls.append(tuple(map(tuple, p.tolist())))
    objects = []
    raw_objects = data.get("objects", []) or []
    if not isinstance(raw_objects, Sequence) or isinstance(raw_objects, str):
        raise LayoutError("'objects' must be a list")
    for i, o in enumerate(raw_objects):
        what = f"objects[{i}]" + (f" ({o.get('name')})" if isinstance(o, Mapping) and o.get("name") else "")
        if not isinstance(o, Mapping):
            raise LayoutError(f"{what}: must be a mapping with 'class' and 'polygon' (or 'center' and 'size')")
        unknown = set(o) - _OBJECT_KEYS
        if unknown:
            raise LayoutError(f"{what}: unknown keys {sorted(unknown)}; allowed: {sorted(_OBJECT_KEYS)}")
        cls = o.get("class")
        if cls not in CLASS_NAMES:
            raise LayoutError(f"{what}: unknown class {cls!r}; known classes: {list(CLASS_NAMES)}")
        if "polygon" in o:
            poly = _ring(o["polygon"], what)
        elif "center" in o and "size" in o:
            poly = _ring(_box(o, what), what)
        else:
            raise LayoutError(f"{what}: needs 'polygon' or both 'center' and 'size'")
        inside = point_in_polygon(poly, outer) | (_dist_points_to_ring(poly, outer) < 1e-6)
        if not np.all(inside):
            raise LayoutError(f"{what}: vertex {poly[~inside][0].tolist()} lies outside the outer wall")
        obj_name = str(o.get("name") or f"{cls}_{i}")
        objects.append(SemanticObject(cls, tuple(map(tuple, poly.tolist())), obj_name))
    return Layout(name, tuple(map(tuple, outer.tolist())), tuple(walls), tuple(objects))


def load_layout(path: str | Path) -> Layout:
    """Load and validate a layout from a ``.json``, ``.yaml`` or ``.yml`` file."""
    path = Path(path)
    if not path.is_file():
        raise LayoutError(f"layout file not found: {path}")
    text = path.read_text()
    try:
        if path.suffix.lower() in (".yaml", ".yml"):
            import yaml

            data = yaml.safe_load(text)
        elif path.suffix.lower() == ".json":
            data = json.loads(text)
        else:
            raise LayoutError(f"{path}: layout files must end in .json, .yaml or .yml")
    except (json.JSONDecodeError, ValueError) as e:
        if isinstance(e, LayoutError):
            raise
        raise LayoutError(f"{path}: not valid {path.suffix[1:].upper()}: {e}") from None
    except Exception as e:  # yaml.YAMLError without importing yaml at module level
        raise LayoutError(f"{path}: not valid YAML: {e}") from None
    try:
        return layout_from_dict(data, default_name=path.stem)
    except LayoutError as e:
        raise LayoutError(f"{path}: {e}") from None
