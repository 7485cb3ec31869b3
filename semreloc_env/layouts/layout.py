"""Layouts: the geometry of a world as plain, validated data.

A layout is the single source of truth for one environment: it builds the pymunk
space (physics and true sensing, `semreloc_env.world`) and rasterises to the
grids a perfect map would hold (`semreloc_env.rasterize`).

File / dict format (JSON or YAML), all lengths in metres::

    name: lab                      # optional
    outer: [[0, 0], [15, 0], [15, 10], [0, 10]]   # closed outer wall polygon
    walls:                         # interior walls: open polylines, >= 2 points
      - [[5, 0], [5, 4]]
    objects:                       # semantic objects, each one of the classes below
      - {class: chair, polygon: [[1, 1], [1.5, 1], [1.5, 1.5], [1, 1.5]]}
      - {class: cabinet, center: [3, 0.3], size: [1.0, 0.5], angle_rad: 0.0}  # box shorthand
      - {class: door, name: entrance, center: [0.05, 5], size: [0.1, 1.0]}  # names: optional, unique
    blocks:                        # optional: solid blocks of no class (pillars, sealed cores)
      - [[6, 6], [7, 6], [7, 7], [6, 7]]                  # a polygon
      - {center: [10, 5], size: [2.0, 1.0], angle_rad: 0.0}  # or the box shorthand

Classes: ``door``, ``chair``, ``trash_bin``, ``cabinet`` (paper 004). Every object is a solid
obstacle for the robot and the lidar, a ``door`` too: the built-in layouts' doors are thin panels
against a wall (the sign a camera recognises), not openings; a door object placed across a
doorway closes it. Openings are gaps between ``walls``. A ``block`` is solid space without a class:
its edges are walls to every sensor (the camera labels them 0, as walls), and no robot is placed
inside it (walls alone that enclose a space leave it free, so starts could be drawn in a sealed room).
Every problem found raises `LayoutError` naming the offending entry.
The user guide, with a worked example and the error messages: docs/layouts.md.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import shapely

from filters.mapping.grid import DEFAULT_CLASS_NAMES
from filters.numbers import is_real, yaml_number_hint
from filters.unique_keys import FileTextError, json_object_pairs, load_yaml

CLASS_NAMES: tuple[str, ...] = DEFAULT_CLASS_NAMES
"""Object classes a layout may use; scan label ``k + 1`` is ``CLASS_NAMES[k]``."""

Point = tuple[float, float]


class LayoutError(ValueError):
    """A layout is malformed; the message names the offending entry."""


@dataclass(frozen=True)
class SemanticObject:
    """One object of a known class: a simple polygon, vertices counter-clockwise (files may give
    either orientation; they are reversed when clockwise), metres."""

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
        outer: the closed outer wall polygon (counter-clockwise; a file may give it clockwise,
            it is reversed); the robot lives inside it.
        walls: interior walls, each an open polyline of >= 2 points.
        objects: the semantic objects.
        blocks: solid polygons of no class (counter-clockwise): their edges are walls, their
            inside is not free space.
    """

    name: str
    outer: tuple[Point, ...]
    walls: tuple[tuple[Point, ...], ...]
    objects: tuple[SemanticObject, ...]
    blocks: tuple[tuple[Point, ...], ...] = ()

    def wall_segments(self) -> np.ndarray:
        """``(M, 2, 2)`` float64: every wall segment (outer ring, interior polylines, then block edges)."""
        segs = [_ring_segments(self.outer)]
        for wall in self.walls:
            w = np.asarray(wall, dtype=np.float64)
            segs.append(np.stack([w[:-1], w[1:]], axis=1))
        segs += [_ring_segments(b) for b in self.blocks]
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
        """The plain-dict form accepted by `layout_from_dict` (round-trips; ``blocks`` only if there are any)."""
        out = {
            "name": self.name,
            "outer": [list(p) for p in self.outer],
            "walls": [[list(p) for p in w] for w in self.walls],
            "objects": [
                {"class": o.cls, "name": o.name, "polygon": [list(p) for p in o.polygon]} for o in self.objects
            ],
        }
        if self.blocks:
            out["blocks"] = [[list(p) for p in b] for b in self.blocks]
        return out


# --------------------------------------------------------------------------- limits
MAX_COORDINATE_M = 2e9
"""Largest accepted ``|x|`` or ``|y|`` (metres): map or UTM coordinates fit, and float64 still
resolves 0.25 micrometres there."""

MAX_VERTICES = 1_000_000
"""Most vertices a layout may hold in total (outer wall, walls, objects and blocks together, a box
shorthand counting 4);
validation runs in ``O(n log n)`` time and ``O(n)`` memory up to this size."""

TOLERANCE_M = 1e-6
"""Objects and walls may touch the outer wall and each other; they may not cross by more than this."""

ZERO_AREA_M2 = 1e-12
"""A polygon whose area is below this (m^2) is degenerate."""

MIN_FREE_AREA_M2 = 0.01
"""A layout whose objects and blocks leave less floor than this (m^2) inside the outer wall is refused."""


# --------------------------------------------------------------------------- geometry
def _ring_segments(ring: Sequence[Point]) -> np.ndarray:
    p = np.asarray(ring, dtype=np.float64)
    return np.stack([p, np.roll(p, -1, axis=0)], axis=1)


def _signed_area(p: np.ndarray) -> float:
    """Shoelace area, computed about the first vertex so large coordinates keep their precision."""
    q = p - p[0]
    x, y = q[:, 0], q[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def point_in_polygon(pts: np.ndarray, poly: np.ndarray, chunk: int = 1 << 22) -> np.ndarray:
    """Even-odd test: bool ``(P,)`` for points ``(P, 2)`` inside ``poly`` ``(V, 2)``.

    Works in blocks of at most ``chunk`` point-edge pairs, so memory stays bounded for big grids.
    """
    pts = np.atleast_2d(np.asarray(pts, dtype=np.float64))
    poly = np.asarray(poly, dtype=np.float64)
    out = np.zeros(len(pts), bool)
    step = max(1, chunk // max(1, len(poly)))
    x0, y0 = poly[:, 0][None, :], poly[:, 1][None, :]
    x1, y1 = np.roll(poly[:, 0], -1)[None, :], np.roll(poly[:, 1], -1)[None, :]
    for s in range(0, len(pts), step):
        x, y = pts[s : s + step, 0:1], pts[s : s + step, 1:2]
        straddle = (y0 > y) != (y1 > y)
        with np.errstate(divide="ignore", invalid="ignore"):
            xc = x0 + (y - y0) * (x1 - x0) / (y1 - y0)
        out[s : s + step] = np.sum(straddle & (x < xc), axis=1) % 2 == 1
    return out


# --------------------------------------------------------------------------- parsing
def _key_list(keys) -> list:
    """Keys sorted for a message even when they are of mixed types (``{"a", 7}``)."""
    return sorted(keys, key=repr)


def _is_number(v) -> bool:
    return is_real(v)


def _is_sequence(raw) -> bool:
    """A list, a tuple or an ndarray of at least one dimension (what `_as_list` takes)."""
    return isinstance(raw, (list, tuple)) or (isinstance(raw, np.ndarray) and raw.ndim >= 1)


def _length(raw) -> int:
    """``len(raw)`` for what `_as_list` takes, else 0 (counted before anything is validated)."""
    return len(raw) if _is_sequence(raw) else 0


def _as_list(raw, what: str, expected: str) -> list:
    """``raw`` as a list if it is a list, tuple or ndarray; LayoutError otherwise."""
    if _is_sequence(raw):
        return list(raw)
    raise LayoutError(f"{what}: expected {expected}, got {type(raw).__name__} {raw!r:.80}")


def _points(raw, what: str, min_points: int) -> np.ndarray:
    """Validate a list of ``[x, y]`` points (real numbers, finite, within MAX_COORDINATE_M)."""
    if isinstance(raw, np.ndarray) and raw.dtype.kind in "iuf" and raw.ndim == 2 and raw.shape[1] == 2:
        p = raw.astype(np.float64)
    else:
        pts = _as_list(raw, what, "a list of [x, y] points")
        if len(pts) > MAX_VERTICES:
            raise LayoutError(f"{what}: {len(pts)} points, more than the limit of {MAX_VERTICES}")
        flat = []
        for i, pt in enumerate(pts):
            if not (isinstance(pt, (list, tuple)) or (isinstance(pt, np.ndarray) and pt.ndim == 1)) or len(pt) != 2:
                raise LayoutError(f"{what}[{i}]: expected an [x, y] point, got {pt!r:.80}")
            _check_numbers(pt, f"{what}[{i}]")
            flat.append(pt)
        p = np.array(flat, dtype=np.float64).reshape(-1, 2)
    if not np.all(np.isfinite(p)):
        raise LayoutError(f"{what}: coordinates must be finite numbers (found NaN or inf)")
    if p.size and np.abs(p).max() > MAX_COORDINATE_M:
        raise LayoutError(f"{what}: coordinates must lie within +-{MAX_COORDINATE_M:g} m, got {np.abs(p).max():g}")
    if len(p) < min_points:
        raise LayoutError(f"{what}: needs at least {min_points} points, got {len(p)}")
    return p


def _check_numbers(pt, what: str) -> None:
    """LayoutError naming ``what`` unless every coordinate of the point ``pt`` is a real number."""
    for v in pt:
        if not _is_number(v):
            raise LayoutError(
                f"{what}: coordinates must be numbers, got {type(v).__name__} {v!r:.40}{yaml_number_hint(v)}"
            )
        if not _fits_float(v):
            raise LayoutError(
                f"{what}: coordinates must be finite numbers, got an integer of {len(str(abs(v)))} digits"
            )


def _fits_float(v) -> bool:
    """A real number converts to a float (a Python int beyond 1.8e308 does not: OverflowError)."""
    try:
        float(v)
    except OverflowError:
        return False
    return True


def _ring(raw, what: str) -> np.ndarray:
    """A simple polygon from its vertices, in either orientation: returned counter-clockwise,
    without repeated vertices."""
    p = _points(raw, what, 3)
    keep = np.ones(len(p), bool)
    keep[1:] = np.any(p[1:] != p[:-1], axis=1)  # exact duplicates only: large coordinates keep their corners
    p = p[keep]
    while len(p) > 1 and np.array_equal(p[0], p[-1]):
        p = p[:-1]  # an explicitly closed ring repeats its first vertex
    if len(p) < 3:
        raise LayoutError(f"{what}: a polygon needs at least 3 distinct vertices, got {len(p)}")
    area = _signed_area(p)
    poly = shapely.polygons(p - p[0])
    if abs(area) < ZERO_AREA_M2 and shapely.convex_hull(poly).area < ZERO_AREA_M2:
        raise LayoutError(
            f"{what}: polygon has zero area (below {ZERO_AREA_M2:g} m^2: its vertices are collinear or too close)"
        )
    reason = shapely.is_valid_reason(poly)
    if reason == "Valid Geometry" and abs(area) < ZERO_AREA_M2:
        raise LayoutError(f"{what}: polygon has zero area")
    if reason != "Valid Geometry":
        m = re.search(r"\[([-\d.eE+]+) ([-\d.eE+]+)\]", reason)
        where = f" near ({float(m[1]) + p[0, 0]:.6g}, {float(m[2]) + p[0, 1]:.6g})" if m else ""
        kind = "self-intersecting" if "intersection" in reason.lower() else f"invalid ({reason})"
        raise LayoutError(f"{what}: polygon is {kind}{where}")
    return p if area > 0 else p[::-1]


def _real(entry: Mapping, key: str, what: str, default: float | None = None) -> float:
    v = entry.get(key, default)
    if not _is_number(v) or not _fits_float(v) or not math.isfinite(v):
        raise LayoutError(f"{what}.{key} must be a finite number, got {v!r:.80}{yaml_number_hint(v)}")
    return float(v)


def _point(raw, what: str) -> np.ndarray:
    """One ``[x, y]`` point, validated as `_points` does; the message names ``what`` itself."""
    if not (isinstance(raw, (list, tuple)) or (isinstance(raw, np.ndarray) and raw.ndim == 1)) or len(raw) != 2:
        raise LayoutError(f"{what}: expected an [x, y] pair of numbers, got {raw!r:.80}")
    _check_numbers(raw, what)
    return _points([raw], what, 1)[0]


def _box(entry: Mapping, what: str) -> np.ndarray:
    c = _point(entry["center"], f"{what}.center")
    size = _point(entry["size"], f"{what}.size")
    if np.any(size <= 0):
        raise LayoutError(f"{what}.size must be positive, got {size.tolist()}")
    ang = _real(entry, "angle_rad", what, 0.0)
    hx, hy = size / 2
    local = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
    rot = np.array([[math.cos(ang), -math.sin(ang)], [math.sin(ang), math.cos(ang)]])
    return local @ rot.T + c


def _where(geom) -> str:
    """`` near (x, y)`` for a representative point of a non-empty geometry (local frame)."""
    if geom.is_empty:
        return ""
    pt = geom.representative_point() if geom.geom_type != "Point" else geom
    return f" near ({pt.x:.6g}, {pt.y:.6g})"


def _check_geometry(outer: np.ndarray, walls: list, walls_what: list, objects: list, objects_what: list) -> None:
    """Containment and overlaps in ``O(n log n)``: walls and objects covered by the outer wall
    (whole edges, not only vertices), no two objects overlapping, no wall through an object.

    Everything is shifted by the outer wall's first vertex so that large coordinates keep
    their precision; reported points are shifted back.
    """
    o = outer[0]
    outer_poly = shapely.polygons(outer - o)
    region = outer_poly.buffer(TOLERANCE_M, join_style="mitre")
    shapely.prepare(region)
    wall_geoms = [shapely.linestrings(w - o) for w in walls]
    obj_geoms = [shapely.polygons(p - o) for p in objects]

    def shifted(geom):
        return shapely.transform(geom, lambda c: c + o)

    for g, what in zip(wall_geoms, walls_what):
        if not region.covers(g):
            raise LayoutError(f"{what}: leaves the outer wall{_where(shifted(g.difference(outer_poly)))} (outside)")
    for g, what in zip(obj_geoms, objects_what):
        if not region.covers(g):
            raise LayoutError(f"{what}: lies partly outside the outer wall{_where(shifted(g.difference(outer_poly)))}")
    if outer_poly.area <= MIN_FREE_AREA_M2:
        raise LayoutError(
            f"outer: encloses {outer_poly.area:.3g} m^2, less than the {MIN_FREE_AREA_M2} m^2 of floor a layout needs"
        )
    if not obj_geoms:
        return
    cores = [g.buffer(-TOLERANCE_M, join_style="mitre") for g in obj_geoms]  # interiors, less the tolerance
    tree = shapely.STRtree(obj_geoms)
    pairs = tree.query(cores, predicate="intersects")  # (2, K): core i meets object j
    for i, j in pairs[:, np.lexsort(pairs[::-1])].T:
        if i < j and not cores[i].intersection(cores[j]).is_empty:
            hit = shifted(cores[i].intersection(cores[j]))
            raise LayoutError(f"{objects_what[j]}: overlaps {objects_what[i]}{_where(hit)}")
    # objects do not overlap (checked above), so their areas add up; a room they fill leaves no floor
    areas = [g.area for g in obj_geoms]
    if outer_poly.area - sum(areas) <= MIN_FREE_AREA_M2:
        raise LayoutError(
            f"{objects_what[int(np.argmax(areas))]}: objects and blocks fill the "
            f"outer wall (less than {MIN_FREE_AREA_M2} m^2 of floor left)"
        )
    if wall_geoms:
        core_tree = shapely.STRtree(cores)
        pairs = core_tree.query(wall_geoms, predicate="intersects")
        if pairs.shape[1]:
            w, k = pairs[:, np.lexsort(pairs[::-1])][:, 0]
            hit = shifted(wall_geoms[w].intersection(cores[k]))
            raise LayoutError(f"{walls_what[w]}: passes through {objects_what[k]}{_where(hit)}")


_TOP_KEYS = {"name", "outer", "walls", "objects", "blocks"}
_OBJECT_KEYS = {"class", "name", "polygon", "center", "size", "angle_rad"}
_BLOCK_KEYS = {"polygon", "center", "size", "angle_rad"}


def _shape(entry: Mapping, what: str) -> np.ndarray:
    """The polygon of an object or block entry: its ``polygon``, or the box of ``center`` and ``size``."""
    if "polygon" in entry:
        box = [k for k in ("center", "size", "angle_rad") if k in entry]
        if box:
            turn = " (a polygon's corners carry its turn)" if box == ["angle_rad"] else ""
            raise LayoutError(
                f"{what}: give either 'polygon' or the box shorthand ('center', 'size' and optionally 'angle_rad'), "
                f"not both: it has 'polygon' and {_key_list(box)}{turn}"
            )
        return _ring(entry["polygon"], what)
    if "center" in entry and "size" in entry:
        return _ring(_box(entry, what), what)
    raise LayoutError(f"{what}: needs 'polygon' or both 'center' and 'size'")


def _block(raw, what: str) -> np.ndarray:
    """A block: a polygon (a list of points) or a mapping with ``polygon`` or ``center`` and ``size``."""
    if isinstance(raw, Mapping):
        unknown = set(raw) - _BLOCK_KEYS
        if unknown:
            raise LayoutError(f"{what}: unknown keys {_key_list(unknown)}; allowed: {sorted(_BLOCK_KEYS)}")
        return _shape(raw, what)
    return _ring(raw, what)


def _optional_list(data: Mapping, key: str) -> list:
    raw = data.get(key)
    if raw is None:
        return []
    return _as_list(raw, f"'{key}'", "a list")


def layout_from_dict(data: Mapping, default_name: str = "layout") -> Layout:
    """Validate a plain dict (see the module docstring) and build a `Layout`.

    Checks, in ``O(n log n)`` time for ``n`` vertices in all (limit `MAX_VERTICES`):
    known keys; coordinates real numbers (not strings or bools), finite, within
    `MAX_COORDINATE_M`; polygons simple (not self-intersecting) with non-zero area;
    whole walls, objects and blocks inside the outer wall; objects and blocks not overlapping
    each other and no interior wall through one (touching, within `TOLERANCE_M`, is fine).

    Raises:
        LayoutError: the first problem found; the message names the entry.
    """
    if not isinstance(data, Mapping):
        raise LayoutError(f"a layout must be a mapping, got {type(data).__name__}")
    unknown = set(data) - _TOP_KEYS
    if unknown:
        raise LayoutError(f"unknown layout keys {_key_list(unknown)}; allowed: {sorted(_TOP_KEYS)}")
    if "outer" not in data:
        raise LayoutError("layout has no 'outer' wall polygon")
    name = data.get("name", default_name)
    if not isinstance(name, str):
        raise LayoutError(f"'name' must be a string, got {type(name).__name__}")
    raw_walls = _optional_list(data, "walls")
    raw_objects = _optional_list(data, "objects")
    raw_blocks = _optional_list(data, "blocks")
    entries = [o for o in [*raw_objects, *raw_blocks] if isinstance(o, Mapping)]
    polygons = [o.get("polygon") for o in entries] + [b for b in raw_blocks if not isinstance(b, Mapping)]
    boxes = 4 * sum("polygon" not in o for o in entries)  # the center/size shorthand makes 4 vertices
    total = boxes + sum(_length(x) for x in [data["outer"], *raw_walls, *polygons])
    if total > MAX_VERTICES:
        raise LayoutError(f"layout has {total} vertices, more than the limit of {MAX_VERTICES}")
    outer = _ring(data["outer"], "outer")
    walls, walls_what = [], []
    for i, w in enumerate(raw_walls):
        what = f"walls[{i}]"
        flat = isinstance(w, (list, tuple)) or (isinstance(w, np.ndarray) and w.ndim == 1)
        if flat and len(w) and all(_is_number(v) for v in w):
            raise LayoutError(
                f"{what}: expected a polyline, a list of [x, y] points, got {w!r:.80}; `walls` is a list of "
                "polylines, so one wall from (1, 2) to (3, 2) is written [[[1, 2], [3, 2]]]"
            )
        p = _points(w, what, 2)
        if np.any(np.all(p[1:] == p[:-1], axis=1)):
            raise LayoutError(f"{what}: repeated consecutive point (zero-length segment)")
        walls.append(p)
        walls_what.append(what)
    objects, objects_what, classes, names = [], [], [], []
    named: dict[str, int] = {}
    for i, o in enumerate(raw_objects):
        if not isinstance(o, Mapping):
            raise LayoutError(f"objects[{i}]: must be a mapping with 'class' and 'polygon' (or 'center' and 'size')")
        obj_name = o.get("name")
        if obj_name is not None and not isinstance(obj_name, str):
            raise LayoutError(f"objects[{i}].name must be a string, got {type(obj_name).__name__}")
        what = f"objects[{i}]" + (f" ({obj_name})" if obj_name else "")
        if obj_name:
            if obj_name in named:
                raise LayoutError(f"{what}: name {obj_name!r:.60} already used by objects[{named[obj_name]}]")
            named[obj_name] = i
        unknown = set(o) - _OBJECT_KEYS
        if unknown:
            raise LayoutError(f"{what}: unknown keys {_key_list(unknown)}; allowed: {sorted(_OBJECT_KEYS)}")
        cls = o.get("class")
        if "class" not in o:
            raise LayoutError(f"{what}: no 'class' key; give one of {list(CLASS_NAMES)}")
        if not isinstance(cls, str) or cls not in CLASS_NAMES:
            raise LayoutError(f"{what}: unknown class {cls!r:.40}; known classes: {list(CLASS_NAMES)}")
        objects.append(_shape(o, what))
        objects_what.append(what)
        classes.append(cls)
        names.append(obj_name or None)
    blocks_what = [f"blocks[{i}]" for i in range(len(raw_blocks))]
    blocks = [_block(b, what) for b, what in zip(raw_blocks, blocks_what)]
    _check_geometry(outer, walls, walls_what, objects + blocks, objects_what + blocks_what)
    for i, cls in enumerate(classes):  # unnamed objects: "<class>_<index>", or "_2", "_3", ... after a name taken
        if names[i] is None:
            base = name_i = f"{cls}_{i}"
            k = 2
            while name_i in named:
                name_i, k = f"{base}_{k}", k + 1
            names[i] = name_i
            named[name_i] = i
    return Layout(
        name,
        tuple(map(tuple, outer.tolist())),
        tuple(tuple(map(tuple, w.tolist())) for w in walls),
        tuple(SemanticObject(c, tuple(map(tuple, p.tolist())), n) for c, p, n in zip(classes, objects, names)),
        tuple(tuple(map(tuple, b.tolist())) for b in blocks),
    )


def load_layout(path: str | Path) -> Layout:
    """Load and validate a layout from a ``.json``, ``.yaml`` or ``.yml`` file (UTF-8 text, with or without a
    byte-order mark; ``~`` is expanded)."""
    path = Path(path).expanduser()
    if path.is_dir():
        raise LayoutError(f"{path} is a folder; give one layout file in it (.json, .yaml or .yml)")
    if not path.is_file():
        raise LayoutError(f"layout file not found: {path}")
    if path.suffix.lower() not in (".yaml", ".yml", ".json"):
        raise LayoutError(f"{path}: layout files must end in .json, .yaml or .yml")
    try:
        text = path.read_bytes().decode("utf-8-sig")  # a byte-order mark, as some editors write, is dropped
    except UnicodeDecodeError as e:
        raise LayoutError(f"{path}: not UTF-8 text (byte {e.start}: {e.reason})") from None
    try:
        if path.suffix.lower() in (".yaml", ".yml"):
            data = load_yaml(text)
        else:
            data = json.loads(text, object_pairs_hook=json_object_pairs)
    except FileTextError as e:
        raise LayoutError(f"{path}: {e}") from None
    except json.JSONDecodeError as e:
        raise LayoutError(f"{path}: not valid JSON: {e}") from None
    except RecursionError:
        raise LayoutError(f"{path}: nested too deeply to read (lists or mappings within each other)") from None
    except Exception as e:  # yaml.YAMLError without importing yaml at module level
        raise LayoutError(f"{path}: not valid YAML: {e}") from None
    try:
        return layout_from_dict(data, default_name=path.stem)
    except LayoutError as e:
        raise LayoutError(f"{path}: {e}") from None
