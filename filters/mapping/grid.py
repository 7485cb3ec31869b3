"""Grid maps: an occupancy grid plus one probability grid per semantic class.

This is the map a filter holds. It is plain data (numpy arrays + metadata) and
knows nothing of the simulator, so maps from a real robot (ROS ``map_server``
files, see `filters.mapping.ros_map`) work the same as maps built in simulation.

Conventions
-----------
* Cell ``(row, col)`` covers ``x in [ox + col*res, ox + (col+1)*res)`` and
  ``y in [oy + row*res, oy + (row+1)*res)``: row 0 is the *bottom* row (smallest
  y), as in ROS ``nav_msgs/OccupancyGrid``. Image files store the top row first;
  `filters.mapping.ros_map` flips on read and write.
* ``occupancy`` holds the probability that a cell is occupied, in ``[0, 1]``;
  ``0.5`` means unknown. A cell is *occupied* above ``occupied_thresh`` and
  *free* below ``free_thresh`` (the map_server defaults 0.65 / 0.196).
* ``semantic[k]`` holds the probability that an object of class
  ``class_names[k]`` occupies the cell. In scans, label ``k + 1`` means
  ``class_names[k]`` and label ``0`` means "no object" (see `NO_CLASS`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from filters.arrays import frozen_array
from filters.numbers import is_int, is_real

NO_CLASS = 0
"""Label of a semantic beam that hit no object of a known class."""

DEFAULT_CLASS_NAMES: tuple[str, ...] = ("door", "chair", "trash_bin", "cabinet")
"""The object classes of paper 004, in label order (label = index + 1)."""


@dataclass(frozen=True, eq=False)
class GridMap:
    """An occupancy grid and per-class semantic grids on the same raster.

    Attributes:
        occupancy: ``(H, W)`` float32, probability of occupied in ``[0, 1]``.
        resolution_m: cell edge length in metres (> 0).
        origin_xy_m: world ``(x, y)`` of the lower-left corner of cell ``(0, 0)``.
        semantic: ``(C, H, W)`` float32 class-occupancy probabilities in ``[0, 1]``
            (``C = len(class_names)``; may be ``C = 0``).
        class_names: names of the semantic classes, label ``k + 1`` is ``class_names[k]``.
        occupied_thresh: occupancy above this is an obstacle.
        free_thresh: occupancy below this is free space.
        semantic_thresh: class probability above this marks a cell as that class.
    """

    occupancy: np.ndarray
    resolution_m: float
    origin_xy_m: tuple[float, float] = (0.0, 0.0)
    semantic: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 0), np.float32))
    class_names: tuple[str, ...] = ()
    occupied_thresh: float = 0.65
    free_thresh: float = 0.196
    semantic_thresh: float = 0.5

    def __post_init__(self) -> None:
        occ = frozen_array(self.occupancy, np.float32)  # the map's own: the caller's array stays as it was
        if occ.ndim != 2 or occ.size == 0:
            raise ValueError(f"occupancy must be a non-empty 2D array, got shape {occ.shape}")
        if not np.all(np.isfinite(occ)) or occ.min() < 0.0 or occ.max() > 1.0:
            raise ValueError("occupancy values must be finite probabilities in [0, 1]")
        for name in ("resolution_m", "occupied_thresh", "free_thresh", "semantic_thresh"):
            v = getattr(self, name)
            if not is_real(v):
                raise ValueError(f"{name} must be a number, got {v!r:.60}")
        if not (np.isfinite(self.resolution_m) and self.resolution_m > 0):
            raise ValueError(f"resolution_m must be a positive number, got {self.resolution_m!r}")
        try:
            origin = tuple(float(v) for v in self.origin_xy_m)
        except (TypeError, ValueError):
            origin = ()
        if len(origin) != 2 or not all(np.isfinite(origin)):
            raise ValueError(f"origin_xy_m must be two finite numbers, got {self.origin_xy_m!r:.60}")
        if isinstance(self.class_names, (str, bytes)):
            raise ValueError(f"class_names must be a sequence of names, got the string {self.class_names!r:.60}")
        names = tuple(str(n) for n in self.class_names)
        sem = frozen_array(self.semantic, np.float32)
        if sem.size == 0:
            sem = np.zeros((len(names),) + occ.shape, np.float32)
            sem.setflags(write=False)
        if sem.shape != (len(names),) + occ.shape:
            raise ValueError(
                f"semantic must have shape {(len(names),) + occ.shape} (classes x occupancy shape), got {sem.shape}"
            )
        if not np.all(np.isfinite(sem)) or (sem.size and (sem.min() < 0.0 or sem.max() > 1.0)):
            raise ValueError("semantic values must be finite probabilities in [0, 1]")
        if len(set(names)) != len(names):
            raise ValueError(f"class_names must be unique, got {names}")
        if not 0.0 <= self.free_thresh <= self.occupied_thresh <= 1.0:
            raise ValueError("need 0 <= free_thresh <= occupied_thresh <= 1")
        if not 0.0 <= self.semantic_thresh <= 1.0:
            raise ValueError(f"semantic_thresh must be in [0, 1], got {self.semantic_thresh!r}")
        object.__setattr__(self, "occupancy", occ)
        object.__setattr__(self, "semantic", sem)
        object.__setattr__(self, "origin_xy_m", origin)
        object.__setattr__(self, "class_names", names)
        object.__setattr__(self, "resolution_m", float(self.resolution_m))

    # ------------------------------------------------------------------ shape
    @property
    def shape(self) -> tuple[int, int]:
        """``(H, W)``: rows, columns."""
        return self.occupancy.shape  # type: ignore[return-value]

    @property
    def extent_m(self) -> tuple[float, float, float, float]:
        """``(x_min, x_max, y_min, y_max)`` of the grid in metres."""
        h, w = self.shape
        ox, oy = self.origin_xy_m
        return ox, ox + w * self.resolution_m, oy, oy + h * self.resolution_m

    def __getstate__(self) -> dict:
        state = dict(self.__dict__)
        state.pop("_derived_arrays", None)  # recomputed on demand; keeps pickles small
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        for name in ("occupancy", "semantic"):  # read-only again, as __post_init__ leaves them
            getattr(self, name).setflags(write=False)

    # ------------------------------------------------------------------ masks
    def _derived(self, key, make) -> np.ndarray:
        """``make()``, computed once per map and read-only (the map's own arrays are read-only, so
        what is derived from them never goes stale)."""
        cache = self.__dict__.setdefault("_derived_arrays", {})  # frozen: bypass __setattr__
        a = cache.get(key)
        if a is None:
            a = make()
            a.setflags(write=False)
            cache[key] = a
        return a

    def occupied_mask(self) -> np.ndarray:
        """``(H, W)`` bool, read-only: cells that are obstacles."""
        return self._derived("occupied", lambda: self.occupancy > self.occupied_thresh)

    def free_mask(self) -> np.ndarray:
        """``(H, W)`` bool, read-only: cells that are known free space."""
        return self._derived("free", lambda: self.occupancy < self.free_thresh)

    def free_cells(self) -> np.ndarray:
        """Flat (row-major) indices of the `free_mask` cells, ascending, read-only."""
        return self._derived("free_cells", lambda: np.flatnonzero(self.free_mask()))

    def _class(self, k) -> int:
        """Class index ``k`` checked (an int in ``[-C, C)``) and made non-negative."""
        if not is_int(k):
            raise TypeError(f"class index must be an int, got {type(k).__name__} {k!r}")
        if not -len(self.class_names) <= k < len(self.class_names):
            raise IndexError(f"class index {k} out of range for {len(self.class_names)} classes")
        return int(k) % len(self.class_names)

    def class_mask(self, k: int) -> np.ndarray:
        """``(H, W)`` bool, read-only: cells labelled with class index ``k`` (label ``k + 1``)."""
        k = self._class(k)
        return self._derived(("class", k), lambda: self.semantic[k] > self.semantic_thresh)

    def class_cells(self, k: int) -> np.ndarray:
        """Flat (row-major) indices of the `class_mask` ``k`` cells, ascending, read-only."""
        k = self._class(k)
        return self._derived(("class_cells", k), lambda: np.flatnonzero(self.class_mask(k)))

    def class_index(self, name: str) -> int:
        """Index ``k`` of a class name (its scan label is ``k + 1``)."""
        try:
            return self.class_names.index(name)
        except ValueError:
            raise KeyError(f"unknown class {name!r}; map classes are {self.class_names}") from None

    # ------------------------------------------------------------ conversions
    def world_to_cell(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Map world points ``(..., 2)`` in metres to integer ``(row, col)`` arrays.

        Points outside the grid give indices outside ``[0, H) x [0, W)``; check
        with `in_bounds`.
        """
        xy = np.asarray(xy, dtype=np.float64)
        ox, oy = self.origin_xy_m
        col = np.floor((xy[..., 0] - ox) / self.resolution_m).astype(np.int64)
        row = np.floor((xy[..., 1] - oy) / self.resolution_m).astype(np.int64)
        return row, col

    def in_bounds(self, row: np.ndarray, col: np.ndarray) -> np.ndarray:
        """Bool array: which ``(row, col)`` lie on the grid."""
        h, w = self.shape
        return (row >= 0) & (row < h) & (col >= 0) & (col < w)

    def cell_centers(self, row: np.ndarray, col: np.ndarray) -> np.ndarray:
        """World ``(..., 2)`` centres of cells ``(row, col)`` in metres."""
        ox, oy = self.origin_xy_m
        x = ox + (np.asarray(col) + 0.5) * self.resolution_m
        y = oy + (np.asarray(row) + 0.5) * self.resolution_m
        return np.stack([x, y], axis=-1)

    def is_free(self, xy: np.ndarray) -> np.ndarray:
        """Bool array: which world points ``(..., 2)`` fall in known free cells."""
        row, col = self.world_to_cell(xy)
        ok = self.in_bounds(row, col)
        out = np.zeros(ok.shape, dtype=bool)
        out[ok] = self.free_mask()[row[ok], col[ok]]
        return out
