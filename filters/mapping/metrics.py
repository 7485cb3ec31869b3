"""Agreement between maps: intersection over union of boolean grids and of GridMap layers.

Used to check a mapping run (`filters.mapping.occupancy`) against the rasterised truth of a layout
(or two maps of the same place against each other). Both maps must share one raster: same
shape, resolution and origin, else ``ValueError`` — no resampling is done here.

A mapping run only ever sees the *surfaces* of walls and objects, and with noisy ranges and
geometry that does not sit on cell faces its marks scatter by about a cell. Two helpers make
the comparison fair: `surface_mask` (truth cells a beam from free space can reach) and
`tolerant_precision_recall` (agreement within ``k`` cells).
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from filters.mapping.grid import GridMap

__all__ = [
    "iou",
    "same_raster",
    "check_same_raster",
    "occupancy_iou",
    "free_iou",
    "class_iou",
    "surface_mask",
    "tolerant_precision_recall",
]


def iou(a: np.ndarray, b: np.ndarray, where: np.ndarray | None = None) -> float:
    """``|a & b| / |a | b|`` of two boolean grids of the same shape (cells counted, no units).

    Args:
        a: boolean array (anything else: ``ValueError``).
        b: boolean array of ``a``'s shape.
        where: optional boolean mask of that shape; only cells where it is ``True`` count
            (e.g. the cells a mapping run could observe).

    Returns:
        A float in ``[0, 1]``; ``1.0`` when both are empty (nothing to find, nothing found).
    """
    a = np.asarray(a)
    b = np.asarray(b)
    if a.shape != b.shape:
        raise ValueError(f"iou: shapes differ, {a.shape} vs {b.shape}")
    if a.dtype != np.bool_ or b.dtype != np.bool_:
        raise ValueError(f"iou: need boolean grids, got {a.dtype} and {b.dtype}")
    if where is not None:
        where = np.asarray(where)
        if where.shape != a.shape or where.dtype != np.bool_:
            raise ValueError(f"iou: where must be a boolean array of shape {a.shape}")
        a = a & where
        b = b & where
    union = int(np.count_nonzero(a | b))
    if union == 0:
        return 1.0
    return int(np.count_nonzero(a & b)) / union


def same_raster(a: GridMap, b: GridMap) -> bool:
    """Whether two maps share shape, resolution and origin (exactly)."""
    return a.shape == b.shape and a.resolution_m == b.resolution_m and a.origin_xy_m == b.origin_xy_m


def check_same_raster(a: GridMap, b: GridMap) -> None:
    """Raise ``ValueError`` describing the difference unless ``a`` and ``b`` share one raster."""
    if not same_raster(a, b):
        raise ValueError(
            f"maps are on different rasters: {a.shape} @ {a.resolution_m} m from {a.origin_xy_m} vs "
            f"{b.shape} @ {b.resolution_m} m from {b.origin_xy_m}"
        )


def occupancy_iou(pred: GridMap, truth: GridMap, where: np.ndarray | None = None) -> float:
    """IoU of the occupied masks (each map's own ``occupied_thresh``); same raster required."""
    check_same_raster(pred, truth)
    return iou(pred.occupied_mask(), truth.occupied_mask(), where)


def free_iou(pred: GridMap, truth: GridMap, where: np.ndarray | None = None) -> float:
    """IoU of the free masks (each map's own ``free_thresh``); same raster required."""
    check_same_raster(pred, truth)
    return iou(pred.free_mask(), truth.free_mask(), where)


def class_iou(
    pred: GridMap, truth: GridMap, classes: tuple[str, ...] | None = None, where: np.ndarray | None = None
) -> dict[str, float]:
    """Per-class IoU of the class masks (each map's own ``semantic_thresh``), classes matched by *name*.

    Args:
        pred: the map to score.
        truth: the reference map, on ``pred``'s raster (else ``ValueError``).
        classes: names to compare; default all of ``truth.class_names``. A name missing from
            either map raises ``KeyError``.
        where: optional boolean mask restricting the cells that count.

    Returns:
        ``{name: iou}`` in the order of ``classes``.
    """
    check_same_raster(pred, truth)
    names = truth.class_names if classes is None else tuple(classes)
    return {n: iou(pred.class_mask(pred.class_index(n)), truth.class_mask(truth.class_index(n)), where) for n in names}


def surface_mask(mask: np.ndarray, free: np.ndarray) -> np.ndarray:
    """Cells of ``mask`` that share an edge with a ``free`` cell: what beams from free space can hit.

    E.g. ``surface_mask(truth.class_mask(k), truth.free_mask())`` is the part of class ``k`` a
    mapping run can observe (object interiors and the far side of thick walls cannot be).
    """
    mask = np.asarray(mask)
    free = np.asarray(free)
    if mask.shape != free.shape or mask.dtype != np.bool_ or free.dtype != np.bool_:
        raise ValueError(f"surface_mask: need two boolean arrays of one shape, got {mask.shape} and {free.shape}")
    return mask & ndimage.binary_dilation(free, structure=ndimage.generate_binary_structure(2, 1))


def tolerant_precision_recall(pred: np.ndarray, truth: np.ndarray, tolerance_cells: int = 1) -> tuple[float, float]:
    """Precision and recall of ``pred`` against ``truth`` with a tolerance of ``tolerance_cells``.

    Precision: fraction of ``pred`` cells within ``tolerance_cells`` (Chebyshev distance, cells)
    of a ``truth`` cell; recall: fraction of ``truth`` cells within that distance of a ``pred``
    cell. ``tolerance_cells = 0`` is exact matching. An empty side scores ``1.0``.
    """
    pred = np.asarray(pred)
    truth = np.asarray(truth)
    if pred.shape != truth.shape or pred.dtype != np.bool_ or truth.dtype != np.bool_:
        raise ValueError(f"need two boolean grids of one shape, got {pred.shape} and {truth.shape}")
    k = int(tolerance_cells)
    if k < 0:
        raise ValueError(f"tolerance_cells must be >= 0, got {tolerance_cells}")

    def near(m: np.ndarray) -> np.ndarray:
        if k == 0 or not m.any():
            return m
        return ndimage.binary_dilation(m, structure=ndimage.generate_binary_structure(2, 2), iterations=k)

    precision = float(near(truth)[pred].mean()) if pred.any() else 1.0
    recall = float(near(pred)[truth].mean()) if truth.any() else 1.0
    return precision, recall


def semantic_surface_quality(mapped: GridMap, truth: GridMap, tolerance_cells: int = 1) -> dict[str, dict[str, float]]:
    """How well a mapping run's class grids match the true objects' *visible* surfaces.

    A mapping run only sees object surfaces, so the truth per class is
    ``surface_mask(truth.class_mask(k), truth.free_mask())``. Per class name:
    ``iou`` (plain IoU with that surface), ``precision`` and ``recall`` (with a
    tolerance of ``tolerance_cells``, `tolerant_precision_recall`).
    """
    check_same_raster(mapped, truth)
    free = truth.free_mask()
    out = {}
    for k, name in enumerate(truth.class_names):
        surface = surface_mask(truth.class_mask(k), free)
        pred = mapped.class_mask(mapped.class_index(name))
        prec, rec = tolerant_precision_recall(pred, surface, tolerance_cells)
        out[name] = {"iou": iou(pred, surface), "precision": prec, "recall": rec}
    return out
