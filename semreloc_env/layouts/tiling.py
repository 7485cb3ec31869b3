"""Large layouts from small ones: a base layout repeated on a grid, tiles joined by doorways.

Used to measure how mapping runs and envs scale with area (``scripts/bench.py``) and to
try policies on building-size worlds.
"""

from __future__ import annotations

import numpy as np

from filters.numbers import is_int

from .layout import Layout, layout_from_dict


def tiled_layout(base: Layout, nx: int, ny: int, doorway_m: float = 0.8, name: str | None = None) -> Layout:
    """``nx x ny`` copies of ``base`` (whose outer wall must be an axis-aligned rectangle).

    Each copy keeps its interior walls and objects; the walls between copies get a
    ``doorway_m`` gap where no object or wall of the base stands near it (the free place
    nearest a quarter of the way along), and one rectangle encloses all copies. The result is
    ``nx`` times as wide and ``ny`` times as deep as ``base``.

    Raises:
        ValueError: ``nx`` or ``ny`` is not a positive int, the base outer wall is not a rectangle,
            or no doorway fits between copies.
    """
    for arg, v in (("nx", nx), ("ny", ny)):
        if not (is_int(v) and v >= 1):
            raise ValueError(f"{arg} must be an int >= 1, got {v!r}")
    outer = np.asarray(base.outer, dtype=np.float64)
    x0, x1, y0, y1 = base.bounds()
    corners = {(x0, y0), (x1, y0), (x1, y1), (x0, y1)}
    if len(outer) != 4 or {tuple(p) for p in outer.tolist()} != corners:
        raise ValueError(f"tiled_layout needs a base whose outer wall is an axis-aligned rectangle, got {base.outer}")
    w, h = x1 - x0, y1 - y0
    if not 0 < doorway_m < min(w, h) / 2:
        raise ValueError(f"doorway_m must be in (0, {min(w, h) / 2}), got {doorway_m!r}")
    gap_x = _gap_centre(base, along_x=True, doorway_m=doorway_m)  # on horizontal shared walls
    gap_y = _gap_centre(base, along_x=False, doorway_m=doorway_m)  # on vertical shared walls
    walls, objects, blocks = [], [], []
    for i in range(nx):
        for j in range(ny):
            dx, dy = i * w, j * h
            for wall in base.walls:
                walls.append([[x + dx, y + dy] for x, y in wall])
            for obj in base.objects:
                objects.append({"class": obj.cls, "polygon": [[x + dx, y + dy] for x, y in obj.polygon]})
            blocks += [[[x + dx, y + dy] for x, y in b] for b in base.blocks]
            # each shared wall once: the bottom and left sides of every tile off the border
            if j > 0:
                y = y0 + dy
                walls += [
                    [[x0 + dx, y], [gap_x - doorway_m / 2 + dx, y]],
                    [[gap_x + doorway_m / 2 + dx, y], [x1 + dx, y]],
                ]
            if i > 0:
                x = x0 + dx
                walls += [
                    [[x, y0 + dy], [x, gap_y - doorway_m / 2 + dy]],
                    [[x, gap_y + doorway_m / 2 + dy], [x, y1 + dy]],
                ]
    big = [[x0, y0], [x0 + nx * w, y0], [x0 + nx * w, y0 + ny * h], [x0, y0 + ny * h]]
    return layout_from_dict(
        {"name": name or f"{base.name}_x{nx}x{ny}", "outer": big, "walls": walls, "objects": objects, "blocks": blocks}
    )


def _gap_centre(base: Layout, along_x: bool, doorway_m: float, depth_m: float = 0.8, margin_m: float = 0.25) -> float:
    """Where along a shared wall the doorway goes: the first of a few candidate positions whose
    gap (plus ``margin_m`` each end) meets no object or interior wall within ``depth_m`` of the
    two base sides that meet there (``along_x``: the bottom and top sides; else left and right)."""
    x0, x1, y0, y1 = base.bounds()
    lo, hi = (x0, x1) if along_x else (y0, y1)
    side_a, side_b = (y0, y1) if along_x else (x0, x1)
    u, v = (0, 1) if along_x else (1, 0)  # coordinate along the wall, across it
    blocked = []
    shapes = [np.asarray(o.polygon, dtype=np.float64) for o in base.objects]
    shapes += [np.asarray(w, dtype=np.float64) for w in [*base.walls, *base.blocks]]
    for pts in shapes:
        across = pts[:, v]
        if min(abs(across - side_a).min(), abs(across - side_b).min()) <= depth_m:
            blocked.append((pts[:, u].min() - margin_m, pts[:, u].max() + margin_m))
    half = doorway_m / 2
    first, last = lo + half + 0.3, hi - half - 0.3  # clear of the corners
    candidates = [first, lo + 0.25 * (hi - lo)] + [b1 + half for _, b1 in blocked]
    ok = [c for c in candidates if first <= c <= last and all(c + half <= b0 or c - half >= b1 for b0, b1 in blocked)]
    if ok:
        return min(ok, key=lambda c: abs(c - (lo + 0.25 * (hi - lo))))
    raise ValueError(f"no room for a {doorway_m} m doorway between copies of layout {base.name!r}")
