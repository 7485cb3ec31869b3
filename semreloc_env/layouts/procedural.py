"""A procedural layout generator: rooms on both sides of a corridor, furnished, from a seed."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from filters.numbers import is_int, is_real

PROCEDURAL_VERSION = 2
"""The procedural generator's version, as `semreloc_env.layouts.get_layout` takes it: 2 checks that a
lookalike layout's corridor objects break its half turn (`ProceduralParams.min_asymmetry_m`); 1 is the
generator before that check (``SemReloc-v2`` and older, ``SemSlam-*``). Layouts that pass the check
are the same in both; the others differ in their corridor objects only."""

_MAX_CORRIDOR_DRAWS = 100
"""Draws of the corridor objects before a lookalike layout gives up on `ProceduralParams.min_asymmetry_m`."""

# A class swap that keeps footprints (used by symmetric layouts): same shape, other class.
_TWIN_CLASS = {"door": "cabinet", "cabinet": "door", "chair": "trash_bin", "trash_bin": "chair"}


@dataclass(frozen=True)
class ProceduralParams:
    """Knobs of `procedural_layout` (metres).

    Attributes:
        rooms_per_side: inclusive range of the number of rooms on each corridor side.
        room_width_m: range of room widths along the corridor.
        room_depth_m: range of room depth (away from the corridor).
        corridor_width_m: range of corridor width.
        doorway_m: doorway width.
        objects_per_room: inclusive range of furniture pieces per room.
        symmetric: make the walls and furniture footprints invariant under a half
            turn about the centre, with furniture classes swapped between the
            twins, so lidar cannot tell the halves apart and semantics can.
        lookalike: every room identical in geometry *and* furniture classes (north rooms
            are half-turned copies of the south ones), told apart only by
            ``corridor_objects`` objects against the corridor walls: from inside a room
            the sensors cannot tell which room it is, only moving out can
            (`lookalike_layout`).
        corridor_objects: inclusive range of the number of corridor objects (lookalike only).
        min_asymmetry_m: lookalike only: the corridor objects must break the half turn that maps
            the rest of the layout onto itself by at least this much (`half_turn_asymmetry`);
            a draw that does not is drawn again from the same generator. 0 switches the check
            off, as generator version 1 (`PROCEDURAL_VERSION`) had it: there 71 of 400 layouts
            checked broke it by less than 1 m (mostly same-class objects on both end walls), 16 of
            them by less than 0.1 m, where no motion can tell a pose from its half-turned image.
    """

    rooms_per_side: tuple[int, int] = (2, 4)
    room_width_m: tuple[float, float] = (3.0, 5.0)
    room_depth_m: tuple[float, float] = (3.0, 4.5)
    corridor_width_m: tuple[float, float] = (1.6, 2.4)
    doorway_m: float = 1.0
    objects_per_room: tuple[int, int] = (1, 3)
    symmetric: bool = False
    lookalike: bool = False
    corridor_objects: tuple[int, int] = (2, 4)
    min_asymmetry_m: float = 1.0

    def __post_init__(self) -> None:
        if self.symmetric and self.lookalike:
            raise ValueError("ProceduralParams: symmetric and lookalike exclude each other")
        lo, hi = self.corridor_objects
        if not (isinstance(lo, int) and isinstance(hi, int) and 0 <= lo <= hi):
            raise ValueError(f"ProceduralParams.corridor_objects must be 0 <= lo <= hi, got {self.corridor_objects!r}")
        m = self.min_asymmetry_m
        if isinstance(m, bool) or not isinstance(m, (int, float)) or not (math.isfinite(m) and m >= 0):
            raise ValueError(f"ProceduralParams.min_asymmetry_m must be a finite number >= 0, got {m!r}")
        if self.lookalike and m > 0 and hi == 0:
            raise ValueError(
                "ProceduralParams: corridor_objects=(0, 0) leaves a lookalike layout symmetric under a half turn; "
                "allow corridor objects or set min_asymmetry_m=0"
            )


def _room_furniture(rng: np.random.Generator, x0: float, x1: float, depth: float, door_x: float, n: int) -> list:
    """Furniture for a south room ``[x0, x1] x [0, depth]`` whose doorway is centred at ``door_x``."""
    placed: list[tuple[float, float, float, float]] = []
    out = []
    for _ in range(n):
        for _attempt in range(30):
            cls = str(rng.choice(["chair", "trash_bin", "cabinet", "door"]))
            if cls in ("cabinet", "door"):  # against the back (outer) wall
                w = float(rng.uniform(0.8, 1.4)) if cls == "cabinet" else 1.0
                h = 0.6 if cls == "cabinet" else 0.1
                cx = float(rng.uniform(x0 + w / 2 + 0.05, x1 - w / 2 - 0.05))
                cy = h / 2
            else:
                w = h = 0.5 if cls == "chair" else 0.4
                cx = float(rng.uniform(x0 + 0.8, x1 - 0.8))
                cy = float(rng.uniform(0.8, depth - 1.2))
                if abs(cx - door_x) < 1.2 and cy > depth - 1.6:
                    continue  # keep the doorway clear
            box = (cx - w / 2 - 0.6, cx + w / 2 + 0.6, cy - h / 2 - 0.6, cy + h / 2 + 0.6)
            if any(not (box[1] < p[0] or p[1] < box[0] or box[3] < p[2] or p[3] < box[2]) for p in placed):
                continue
            placed.append((cx - w / 2, cx + w / 2, cy - h / 2, cy + h / 2))
            out.append({"class": cls, "center": [cx, cy], "size": [w, h]})
            break
    return out


def _widths_summing_to(rng: np.random.Generator, length: float, width_range: tuple[float, float]) -> np.ndarray:
    """Room widths within ``width_range`` that add up to ``length`` (as many rooms as fit)."""
    lo, hi = width_range
    n = int(rng.integers(math.ceil(length / hi - 1e-9), math.floor(length / lo + 1e-9) + 1))
    w = rng.uniform(lo, hi, size=n)
    w *= length / w.sum()
    if w.min() < lo or w.max() > hi:  # the rescaling pushed one out of range: equal widths fit
        w = np.full(n, length / n)
    return w


def procedural_layout(rng: np.random.Generator, params: ProceduralParams | None = None) -> dict:
    """Generate a furnished corridor-and-rooms layout (dict form) from ``rng``.

    The same generator state gives the same layout. Validate it with
    `semreloc_env.layouts.layout_from_dict` (``get_layout`` does).
    """
    p = params or ProceduralParams()
    if p.lookalike:
        return lookalike_layout(rng, p)[0]
    n = int(rng.integers(p.rooms_per_side[0], p.rooms_per_side[1] + 1))
    south_w = rng.uniform(*p.room_width_m, size=n)
    length = float(south_w.sum())
    depth = float(rng.uniform(*p.room_depth_m))
    corridor = float(rng.uniform(*p.corridor_width_m))
    height = 2 * depth + corridor
    south_x = np.concatenate([[0.0], np.cumsum(south_w)])
    if p.symmetric:
        north_x = length - south_x[::-1]
    else:
        north_x = np.concatenate([[0.0], np.cumsum(_widths_summing_to(rng, length, p.room_width_m))])
        north_x[-1] = length
    half = p.doorway_m / 2

    def doors(xs):
        return [float(rng.uniform(a + half + 0.3, b - half - 0.3)) for a, b in zip(xs[:-1], xs[1:])]

    south_doors = doors(south_x)
    north_doors = [length - d for d in south_doors[::-1]] if p.symmetric else doors(north_x)

    def wall_with_gaps(y, gaps):
        xs = [0.0] + [v for g in gaps for v in (g - half, g + half)] + [length]
        return [[[xs[i], y], [xs[i + 1], y]] for i in range(0, len(xs), 2)]

    walls = wall_with_gaps(depth, south_doors) + wall_with_gaps(depth + corridor, north_doors)
    walls += [[[x, 0.0], [x, depth]] for x in south_x[1:-1]]
    walls += [[[x, depth + corridor], [x, height]] for x in north_x[1:-1]]

    objects = []
    for a, b, d in zip(south_x[:-1], south_x[1:], south_doors):
        objects += _room_furniture(
            rng, a, b, depth, d, int(rng.integers(p.objects_per_room[0], p.objects_per_room[1] + 1))
        )
    if p.symmetric:
        objects += [
            {
                "class": _TWIN_CLASS[o["class"]],
                "center": [length - o["center"][0], height - o["center"][1]],
                "size": o["size"],
            }
            for o in list(objects)
        ]
    else:
        for a, b, d in zip(north_x[:-1], north_x[1:], north_doors):
            k = int(rng.integers(p.objects_per_room[0], p.objects_per_room[1] + 1))
            for o in _room_furniture(rng, length - b, length - a, depth, length - d, k):
                objects.append({**o, "center": [length - o["center"][0], height - o["center"][1]]})
    return {
        "name": "procedural_sym" if p.symmetric else "procedural",
        "outer": [[0.0, 0.0], [length, 0.0], [length, height], [0.0, height]],
        "walls": walls,
        "objects": objects,
    }


_CORRIDOR_OBJECTS = {"cabinet": (0.9, 0.35), "trash_bin": (0.4, 0.4), "chair": (0.45, 0.45), "door": (1.0, 0.1)}
"""Footprints (along the wall, away from it) of the objects placed in a lookalike corridor, metres."""


def lookalike_layout(rng: np.random.Generator, params: ProceduralParams | None = None) -> tuple[dict, list]:
    """A layout of identical rooms told apart only by objects in the corridor, and its room frames.

    ``n`` equal rooms of width ``W`` south of the corridor, each with its doorway at the same
    offset and the same furniture (same classes and footprints); north of it their half-turned
    copies (a half turn maps a south room onto a north one, so a robot inside sees the same).
    Between ``corridor_objects`` objects of random classes stand against the corridor walls,
    clear of the doorways and of each other (no two overlap along the corridor, so it stays
    passable), and against its end walls.

    Returns:
        ``(layout dict, frames)``: ``frames[i] = (x, y, theta)`` is room ``i``'s frame, so that
        the local pose ``(u, v, phi)`` of the south room 0 sits at
        ``(x + u cos theta - v sin theta, y + u sin theta + v cos theta, theta + phi)`` in room
        ``i`` (south rooms first, west to east, then north rooms). A pose and its images in the
        other rooms see the same room.
    """
    p = params or ProceduralParams(lookalike=True)
    n = int(rng.integers(p.rooms_per_side[0], p.rooms_per_side[1] + 1))
    width = float(rng.uniform(*p.room_width_m))
    length = n * width
    depth = float(rng.uniform(*p.room_depth_m))
    corridor = float(rng.uniform(*p.corridor_width_m))
    height = 2 * depth + corridor
    half = p.doorway_m / 2
    offset = float(rng.uniform(half + 0.3, width - half - 0.3))
    south_x = width * np.arange(n + 1)
    south_doors = [float(x + offset) for x in south_x[:-1]]
    north_doors = [length - d for d in south_doors[::-1]]

    def wall_with_gaps(y, gaps):
        xs = [0.0] + [v for g in gaps for v in (g - half, g + half)] + [length]
        return [[[xs[i], y], [xs[i + 1], y]] for i in range(0, len(xs), 2)]

    walls = wall_with_gaps(depth, south_doors) + wall_with_gaps(depth + corridor, north_doors)
    walls += [[[float(x), 0.0], [float(x), depth]] for x in south_x[1:-1]]
    walls += [[[float(x), depth + corridor], [float(x), height]] for x in south_x[1:-1]]

    k = int(rng.integers(p.objects_per_room[0], p.objects_per_room[1] + 1))
    room = _room_furniture(rng, 0.0, width, depth, offset, k)
    frames = [(float(x), 0.0, 0.0) for x in south_x[:-1]] + [(length - float(x), height, math.pi) for x in south_x[:-1]]
    objects = []
    for fx, fy, ft in frames:
        c, s_ = math.cos(ft), math.sin(ft)
        for o in room:
            u, v = o["center"]
            objects.append({**o, "center": [fx + c * u - s_ * v, fy + s_ * u + c * v]})

    for _ in range(_MAX_CORRIDOR_DRAWS):
        extra = _corridor_objects(rng, p, length, depth, corridor, south_doors, north_doors, half)
        if p.min_asymmetry_m <= 0 or half_turn_asymmetry(extra, length, height) >= p.min_asymmetry_m:
            break
    else:
        raise ValueError(
            f"lookalike_layout: no draw of corridor objects in {_MAX_CORRIDOR_DRAWS} broke the half turn by "
            f"min_asymmetry_m={p.min_asymmetry_m} m; lower it or allow more corridor objects"
        )
    objects += extra
    layout = {
        "name": "procedural_lookalike",
        "outer": [[0.0, 0.0], [length, 0.0], [length, height], [0.0, height]],
        "walls": walls,
        "objects": objects,
    }
    return layout, frames


def half_turn_asymmetry(objects: list, length: float, height: float) -> float:
    """How far ``objects`` (layout-dict objects) are from mapping onto themselves under the half turn
    about the centre of a ``length`` x ``height`` layout, metres.

    For each object, the distance from its half-turned centre to the nearest centre of an object of
    the same class (itself included); the largest of these. 0 for no objects. An object whose
    image lands far from any object of its class tells a pose from its half-turned image.
    """
    if not objects:
        return 0.0
    centres = np.array([o["center"] for o in objects], dtype=np.float64)
    return _farthest_from_class(objects, centres, np.array([length, height]) - centres)


def _farthest_from_class(objects: list, centres: np.ndarray, images: np.ndarray) -> float:
    """The largest distance from an object's image ``images[i]`` to the nearest centre of its class."""
    classes = np.array([o["class"] for o in objects])
    worst = 0.0
    for i, cls in enumerate(classes):
        same = centres[classes == cls]
        worst = max(worst, float(np.min(np.hypot(*(same - images[i]).T))))
    return worst


def _corridor_objects(rng, p, length, depth, corridor, south_doors, north_doors, half) -> list:
    """Objects against the corridor's long walls (clear of doorways) and end walls."""
    n_obj = int(rng.integers(p.corridor_objects[0], p.corridor_objects[1] + 1))
    gaps = [(d - half - 0.3, d + half + 0.3) for d in south_doors + north_doors]
    taken: list[tuple[float, float]] = []  # x intervals already used along the corridor (+ margins)
    ends_used: set[str] = set()
    out = []
    for _ in range(n_obj):
        for _attempt in range(50):
            cls = str(rng.choice(sorted(_CORRIDOR_OBJECTS)))
            along, away = _CORRIDOR_OBJECTS[cls]
            side = str(rng.choice(["south", "north", "west", "east"]))
            if side in ("west", "east"):
                if side in ends_used or along > corridor - 0.6:
                    continue
                x0 = 0.0 if side == "west" else length - away
                interval = (x0 - 0.6, x0 + away + 0.6)
                if any(not (interval[1] < a or b < interval[0]) for a, b in taken):
                    continue
                cy = float(rng.uniform(depth + along / 2 + 0.05, depth + corridor - along / 2 - 0.05))
                out.append({"class": cls, "center": [x0 + away / 2, cy], "size": [away, along]})
                ends_used.add(side)
                taken.append(interval)
                break
            cx = float(rng.uniform(along / 2 + 0.8, length - along / 2 - 0.8))
            interval = (cx - along / 2 - 0.5, cx + along / 2 + 0.5)
            if any(not (interval[1] < a or b < interval[0]) for a, b in gaps + taken):
                continue
            cy = depth + away / 2 if side == "south" else depth + corridor - away / 2
            out.append({"class": cls, "center": [cx, cy], "size": [along, away]})
            taken.append(interval)
            break
    return out


# ------------------------------------------------------------------------------------ ring layouts
def _check_real_ranges(params, *names: str) -> None:
    """ValueError unless each field of ``params`` named is two finite numbers ``(lo, hi)``."""
    for name in names:
        v = getattr(params, name)
        if not (isinstance(v, (tuple, list)) and len(v) == 2 and all(is_real(x) and math.isfinite(x) for x in v)):
            raise ValueError(f"{type(params).__name__}.{name} must be two finite numbers (lo, hi), got {v!r}")


def _check_count_ranges(params, *names: str, most: int | None = None) -> None:
    """ValueError unless each field of ``params`` named is two integers ``0 <= lo <= hi`` (``<= most`` if given)."""
    owner = type(params).__name__
    for name in names:
        v = getattr(params, name)
        if not (isinstance(v, (tuple, list)) and len(v) == 2 and all(is_int(x) for x in v)):
            raise ValueError(f"{owner}.{name} must be two integers (lo, hi), got {v!r}")
        if not (0 <= v[0] <= v[1] and (most is None or v[1] <= most)):
            bound = "" if most is None else f" <= {most}"
            raise ValueError(f"{owner}.{name} must be 0 <= lo <= hi{bound}, got {v!r}")


def _check_telling(params, symmetric: str) -> None:
    """ValueError unless ``params`` asks for at least one telling object and a finite ``min_asymmetry_m >= 0``
    (``symmetric``: what the layout would be without telling objects)."""
    owner = type(params).__name__
    if params.telling_objects[0] < 1:
        raise ValueError(f"{owner}.telling_objects: at least one telling object, or {symmetric}")
    m = params.min_asymmetry_m
    if not (is_real(m) and math.isfinite(m) and m >= 0):
        raise ValueError(f"{owner}.min_asymmetry_m must be a finite number >= 0, got {m!r}")


@dataclass(frozen=True)
class RingParams:
    """Knobs of `ring_layout` (metres).

    Attributes:
        side_m: range of the square hall's side.
        corridor_m: range of the ring corridor's width (the solid core's side is ``side - 2 * corridor``).
        objects_per_quarter: inclusive range of the furniture pieces drawn for one quarter of the ring
            (the other three quarters hold its quarter-turned copies); a piece that finds no room in
            50 tries is left out, so crowded quarters hold fewer.
        telling_objects: inclusive range of the objects placed once, anywhere along the ring (as many
            as find room).
        min_asymmetry_m: every quarter turn about the centre (90, 180 and 270 degrees) must move some
            telling object at least this far from every object of its class (`quarter_turn_asymmetry`);
            a draw that does not is drawn again from the same generator.
    """

    side_m: tuple[float, float] = (10.0, 14.0)
    corridor_m: tuple[float, float] = (2.5, 3.5)
    objects_per_quarter: tuple[int, int] = (1, 3)
    telling_objects: tuple[int, int] = (1, 2)
    min_asymmetry_m: float = 1.0

    def __post_init__(self) -> None:
        _check_real_ranges(self, "side_m", "corridor_m")
        (s0, s1), (c0, c1) = self.side_m, self.corridor_m
        if not (0 < c0 <= c1 and 0 < s0 <= s1 and s0 - 2 * c1 >= 1.0 and c0 >= 2.0):
            raise ValueError(
                f"RingParams: need 2 <= corridor_m[0] <= corridor_m[1] and side_m[0] - 2 * corridor_m[1] >= 1 "
                f"(a core of at least 1 m), got side_m={self.side_m!r}, corridor_m={self.corridor_m!r}"
            )
        _check_count_ranges(self, "objects_per_quarter", "telling_objects")
        _check_telling(self, "the ring is symmetric")


_WALL_OBJECTS = {"cabinet": (1.0, 0.5), "door": (1.0, 0.1), "chair": (0.5, 0.5), "trash_bin": (0.4, 0.4)}
"""Footprints (along the wall, away from it) of the objects of ring and corridor layouts, metres."""

_MAX_RING_DRAWS = 100
"""Draws of the telling objects before `ring_layout` gives up on `RingParams.min_asymmetry_m`."""


def quarter_turn(points: np.ndarray, k: int, side: float) -> np.ndarray:
    """``points`` ``(..., 2)`` turned by ``k`` quarter turns counter-clockwise about the centre of a
    ``side`` x ``side`` square with a corner at the origin (exact for k = 0..3)."""
    x, y = points[..., 0], points[..., 1]
    for _ in range(k % 4):
        x, y = side - y, x
    return np.stack([x, y], axis=-1)


def _turned(obj: dict, k: int, side: float) -> dict:
    """A box object dict turned by ``k`` quarter turns about the centre of the ``side`` square (its
    size's axes swap at odd turns)."""
    c = quarter_turn(np.array(obj["center"], dtype=np.float64), k, side)
    w, h = obj["size"]
    return {"class": obj["class"], "center": [float(c[0]), float(c[1])], "size": [w, h] if k % 2 == 0 else [h, w]}


def quarter_turn_asymmetry(objects: list, side: float) -> float:
    """How far ``objects`` (layout-dict objects) are from mapping onto themselves under the quarter
    turns about the centre of a ``side`` x ``side`` square, metres: for each turn (90, 180, 270
    degrees), the largest distance from an object's turned centre to the nearest centre of its class
    (`half_turn_asymmetry`'s measure); the smallest of the three. 0 for no objects. It is map-wide: above
    a few tenths of a metre no turn maps the furniture onto itself, so some place tells every pose from
    its turned images, though a pose far from that place sees what they see."""
    if not objects:
        return 0.0
    centres = np.array([o["center"] for o in objects], dtype=np.float64)
    return min(_farthest_from_class(objects, centres, quarter_turn(centres, k, side)) for k in (1, 2, 3))


def _wall_gap(rng, cls: str) -> float:
    """How far a ``cls`` object stands off its wall, metres: cabinets and doors touch it (no draw), chairs and bins
    stand 0.05-0.25 m off (one draw)."""
    return 0.0 if cls in ("cabinet", "door") else float(rng.uniform(0.05, 0.25))


def _wall_box(cls: str, cx: float, gap: float, far_y: float, near: bool) -> dict:
    """A ``cls`` box centred at ``cx`` along a wall, ``gap`` off the wall at ``y = 0`` (``near``) or off the one at
    ``y = far_y`` (facing it)."""
    along, away = _WALL_OBJECTS[cls]
    cy = gap + away / 2 if near else far_y - gap - away / 2
    return {"class": cls, "center": [cx, cy], "size": [along, away]}


def _clear_of(span: tuple[float, float], taken: list, margin_m: float = 0.3) -> bool:
    """Whether the x interval ``span`` keeps ``margin_m`` from every interval of ``taken``."""
    return all(span[1] + margin_m <= a or b + margin_m <= span[0] for a, b in taken)


def _against_wall(rng, cls: str, corridor: float, lo: float, hi: float, wall: str):
    """A ``cls`` object against the south outer wall (``wall="outer"``) or the core's south face
    (``"core"``), centred at an ``x`` in ``[lo, hi]`` (its footprint inside); ``(dict, x interval)``."""
    along = _WALL_OBJECTS[cls][0]
    gap = _wall_gap(rng, cls)
    cx = float(rng.uniform(lo + along / 2, hi - along / 2))
    return _wall_box(cls, cx, gap, corridor, wall == "outer"), (cx - along / 2, cx + along / 2)


def ring_layout(rng: np.random.Generator, params: RingParams | None = None) -> dict:
    """A square hall around a solid square core: a ring corridor whose four quarters look alike.

    The furniture of one quarter (the south corridor with its south-west corner) stands against the
    outer wall or the core, and the other three quarters hold its quarter-turned copies: a pose and
    its three images about the centre see the same, but for ``telling_objects`` objects placed once
    along the ring, which must break every quarter turn by ``min_asymmetry_m``
    (`quarter_turn_asymmetry`). Only driving round to them, or far enough to see that they are
    missing, tells the quarters apart. Objects leave at least ``corridor - 1.6`` m of the corridor's
    width free, and keep 0.3 m from each other along a wall.

    Returns a layout dict (`semreloc_env.layouts.layout_from_dict` validates it); the same generator
    state gives the same layout.
    """
    p = params or RingParams()
    side = float(rng.uniform(*p.side_m))
    corridor = float(rng.uniform(*p.corridor_m))
    core = [
        [corridor, corridor],
        [side - corridor, corridor],
        [side - corridor, side - corridor],
        [corridor, side - corridor],
    ]
    classes = sorted(_WALL_OBJECTS)

    def place(n: int, taken: dict, x_range: tuple[float, float]) -> list:
        out = []
        for _ in range(n):
            for _attempt in range(50):
                cls = str(rng.choice(classes))
                wall = str(rng.choice(["outer", "core"]))
                lo, hi = x_range if wall == "outer" else (max(x_range[0], corridor), min(x_range[1], side - corridor))
                if hi - lo < _WALL_OBJECTS[cls][0] + 0.2:
                    continue
                obj, span = _against_wall(rng, cls, corridor, lo + 0.1, hi - 0.1, wall)
                if not _clear_of(span, taken[wall]):
                    continue
                taken[wall].append(span)
                out.append(obj)
                break
        return out

    # one quarter: the south corridor from the west wall to where the south-east corner (the next
    # quarter's) begins, less a margin, so that turned copies never meet
    quarter_x = (0.0, side - corridor - 0.5)
    taken: dict[str, list] = {"outer": [], "core": []}
    n = int(rng.integers(p.objects_per_quarter[0], p.objects_per_quarter[1] + 1))
    quarter = place(n, taken, quarter_x)
    objects = [_turned(o, k, side) for k in range(4) for o in quarter]
    placed = False
    for _ in range(_MAX_RING_DRAWS):
        # a telling object goes into one of the four quarters, placed in its south-quarter frame and turned there
        extra = []
        busy = {"outer": list(taken["outer"]), "core": list(taken["core"])}
        for _t in range(int(rng.integers(p.telling_objects[0], p.telling_objects[1] + 1))):
            k = int(rng.integers(0, 4))
            extra += [_turned(o, k, side) for o in place(1, busy, quarter_x)]
        placed |= bool(extra)
        if extra and (p.min_asymmetry_m <= 0 or quarter_turn_asymmetry(objects + extra, side) >= p.min_asymmetry_m):
            break
    else:
        if not placed:
            raise ValueError(
                f"ring_layout: no room for a telling object in {_MAX_RING_DRAWS} draws beside the quarter's "
                f"furniture (side {side:.2f} m, corridor {corridor:.2f} m); allow fewer objects per quarter or a "
                "larger hall"
            )
        raise ValueError(
            f"ring_layout: no draw of telling objects in {_MAX_RING_DRAWS} broke every quarter turn by "
            f"min_asymmetry_m={p.min_asymmetry_m} m; lower it or allow more telling objects"
        )
    return {
        "name": "procedural_ring",
        "outer": [[0.0, 0.0], [side, 0.0], [side, side], [0.0, side]],
        "walls": [],
        "objects": objects + extra,
        "blocks": [core],
    }


# -------------------------------------------------------------------------------- corridor layouts
@dataclass(frozen=True)
class CorridorParams:
    """Knobs of `corridor_layout` (metres).

    Attributes:
        length_m: range of the corridor's length (the lidar sees 8 m, so a long corridor has a middle
            from which neither end wall is in range).
        width_m: range of the corridor's width.
        period_m: range of the period at which the furniture repeats along the corridor.
        objects_per_period: inclusive range of the furniture pieces of one period (against either long
            wall; a piece that finds no room in 50 tries is left out), at most `MAX_CORRIDOR_COUNT`.
        telling_objects: inclusive range of the objects placed once along the corridor (as many as find
            room), at most `MAX_CORRIDOR_COUNT`.
        min_asymmetry_m: a telling object's centre keeps at least this distance from every whole-period
            shift of every furniture piece of its class and of the telling objects placed before it
            (`period_shift_distance`), so no shift of a pose by whole periods sees it where the pose does; a
            draw that does not is drawn again.

    The length is at most `MAX_CORRIDOR_LENGTH_M`.
    """

    length_m: tuple[float, float] = (18.0, 32.0)
    width_m: tuple[float, float] = (2.4, 3.4)
    period_m: tuple[float, float] = (3.0, 6.0)
    objects_per_period: tuple[int, int] = (1, 3)
    telling_objects: tuple[int, int] = (1, 2)
    min_asymmetry_m: float = 1.0

    def __post_init__(self) -> None:
        _check_real_ranges(self, "length_m", "width_m", "period_m")
        for name in ("length_m", "width_m", "period_m"):
            v = getattr(self, name)
            if not 0 < v[0] <= v[1]:
                raise ValueError(f"CorridorParams.{name} must be 0 < lo <= hi, got {v!r}")
        if self.length_m[1] > MAX_CORRIDOR_LENGTH_M:
            raise ValueError(f"CorridorParams.length_m: at most {MAX_CORRIDOR_LENGTH_M} m long, got {self.length_m!r}")
        if self.width_m[0] < 2.0:
            raise ValueError(f"CorridorParams.width_m: at least 2 m wide, got {self.width_m!r}")
        if self.period_m[0] < 1.5:
            raise ValueError(f"CorridorParams.period_m: a period of at least 1.5 m, got {self.period_m!r}")
        if self.length_m[0] < 2 * self.period_m[1]:
            raise ValueError(
                f"CorridorParams: length_m[0] must hold two of the longest periods, got length_m={self.length_m!r}, "
                f"period_m={self.period_m!r}"
            )
        _check_count_ranges(self, "objects_per_period", "telling_objects", most=MAX_CORRIDOR_COUNT)
        _check_telling(self, "the corridor is periodic")


MAX_CORRIDOR_LENGTH_M = 1000.0
"""Longest corridor `CorridorParams` accepts, metres."""

MAX_CORRIDOR_COUNT = 20
"""Most furniture pieces per period, and most telling objects, `CorridorParams` accepts."""

_MAX_TELLING_DRAWS = 100
"""Draws of one telling object before `corridor_layout` gives up on it (`CorridorParams.min_asymmetry_m`)."""


def period_shift_distance(obj: dict, objects: list, period: float) -> float:
    """How far ``obj`` (a layout-dict object) lies from every whole-period shift along x of every object of
    its class in ``objects``, metres (``inf`` when there is none): the distance, over those objects and the
    shifts ``k * period`` (any integer ``k``), to the nearest shifted centre.

    Raises:
        ValueError: ``period`` is not a finite number > 0.
    """
    if not (is_real(period) and math.isfinite(period) and period > 0):
        raise ValueError(f"period must be a finite number > 0, got {period!r}")
    best = math.inf
    x, y = obj["center"]
    for o in objects:
        if o["class"] != obj["class"]:
            continue
        ox, oy = o["center"]
        dx = (x - ox) - period * round((x - ox) / period)
        best = min(best, math.hypot(dx, y - oy))
    return best


def corridor_layout(rng: np.random.Generator, params: CorridorParams | None = None) -> dict:
    """A long corridor whose furniture repeats at one period: a pose and its shifts by whole periods see
    the same until an end wall or a telling object comes into view.

    One period's furniture (doors flat on a long wall, cabinets against it, chairs and bins standing off
    it) is drawn once and repeated along the corridor, centred so that both ends keep the same margin;
    ``telling_objects`` objects are then placed once, each at least ``min_asymmetry_m`` from every
    whole-period shift of the furniture of its class and of the telling objects before it
    (`period_shift_distance`). A telling object is first sought on free wall (50 draws); failing that
    (no free wall, or none far enough from its class's shifts), in the place of a piece of furniture,
    which is then missing from its period (50 draws). No two pieces overlap along the corridor (0.3 m
    apart), so it stays passable.

    Returns a layout dict (`semreloc_env.layouts.layout_from_dict` validates it); the same generator
    state gives the same layout.
    """
    p = params or CorridorParams()
    length = float(rng.uniform(*p.length_m))
    width = float(rng.uniform(*p.width_m))
    period = float(rng.uniform(*p.period_m))
    n_periods = int(length // period)
    start = (length - n_periods * period) / 2
    classes = sorted(_WALL_OBJECTS)

    def piece(cls: str, cx: float) -> dict:
        near = str(rng.choice(["south", "north"])) == "south"
        return _wall_box(cls, cx, _wall_gap(rng, cls), width, near)

    pattern, taken = [], []  # one period's pieces, in x from the period's start
    for _ in range(int(rng.integers(p.objects_per_period[0], p.objects_per_period[1] + 1))):
        for _attempt in range(50):
            cls = str(rng.choice(classes))
            along = _WALL_OBJECTS[cls][0]  # at most 1 m, and a period is at least 1.5 m
            cx = float(rng.uniform(0.15 + along / 2, period - 0.15 - along / 2))
            span = (cx - along / 2, cx + along / 2)
            # pieces of neighbouring periods must keep their distance too
            if not _clear_of(span, [(a + k * period, b + k * period) for a, b in taken for k in (-1, 0, 1)]):
                continue
            taken.append(span)
            pattern.append(piece(cls, cx))
            break
    furniture = [
        {**o, "center": [start + k * period + o["center"][0], o["center"][1]]}
        for k in range(n_periods)
        for o in pattern
    ]
    spans = [(o["center"][0] - o["size"][0] / 2, o["center"][0] + o["size"][0] / 2) for o in furniture]

    telling: list = []
    for _ in range(int(rng.integers(p.telling_objects[0], p.telling_objects[1] + 1))):
        for attempt in range(_MAX_TELLING_DRAWS):
            cls = str(rng.choice(classes))
            along = _WALL_OBJECTS[cls][0]
            # the first half of the tries look for free wall; the second half put the object in place of a
            # piece of furniture (free wall may be lacking, or too near its class's shifts)
            in_place = bool(furniture) and attempt >= _MAX_TELLING_DRAWS // 2
            gone = int(rng.integers(len(furniture))) if in_place else None
            if gone is None:
                cx = float(rng.uniform(0.4 + along / 2, length - 0.4 - along / 2))
            else:
                cx = min(max(furniture[gone]["center"][0], 0.4 + along / 2), length - 0.4 - along / 2)
            span = (cx - along / 2, cx + along / 2)
            if not _clear_of(span, [s for i, s in enumerate(spans) if i != gone]):
                continue
            obj = piece(cls, cx)
            kept = [o for i, o in enumerate(furniture) if i != gone]
            if p.min_asymmetry_m > 0 and period_shift_distance(obj, kept + telling, period) < p.min_asymmetry_m:
                continue
            if gone is not None:
                del furniture[gone], spans[gone]
            telling.append(obj)
            spans.append(span)
            break
    if not telling:
        raise ValueError(
            f"corridor_layout: no telling object found room {_MAX_TELLING_DRAWS} times at least "
            f"min_asymmetry_m={p.min_asymmetry_m} m from the period's furniture (length {length:.2f} m, period "
            f"{period:.2f} m); lower it or allow fewer objects per period"
        )
    return {
        "name": "procedural_corridor",
        "outer": [[0.0, 0.0], [length, 0.0], [length, width], [0.0, width]],
        "walls": [],
        "objects": furniture + telling,
    }
