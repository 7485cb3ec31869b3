"""Landmark-map errors of a SLAM estimate against the true landmarks (metres).

Two directions, because the two questions differ:

* `map_landmark_errors` -- for each landmark *in the estimated map*, how far it is from the true
  landmark it stands for (by id under known association, else the nearest true landmark). Spurious map
  landmarks count; true landmarks never mapped do not.
* `true_landmark_errors` -- for each *true* landmark asked about (e.g. those seen so far), how far
  the map's estimate of it is (by id, ``inf`` when it has none; else the nearest map landmark, ``inf``
  for an empty map). Unmapped landmarks count; spurious ones do not.
"""

from __future__ import annotations

import numpy as np

__all__ = ["map_landmark_errors", "true_landmark_errors"]


def _xy(a, name: str) -> np.ndarray:
    a = np.asarray(a, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != 2:
        raise ValueError(f"{name} must have shape (K, 2), got {a.shape}")
    return a


def _ids(ids, n: int, name: str) -> np.ndarray:
    ids = np.asarray(ids, dtype=np.int64)
    if ids.shape != (n,):
        raise ValueError(f"{name} must have shape ({n},), got {ids.shape}")
    return ids


def map_landmark_errors(est_xy, est_ids, true_xy, known_association: bool) -> np.ndarray:
    """Distance ``(K,)`` from each of the ``K`` estimated landmarks to its true landmark.

    ``est_xy (K, 2)``, ``est_ids (K,)`` (indices into ``true_xy``; used only with known association),
    ``true_xy (M, 2)``. Without known association the nearest true landmark is taken.
    """
    est_xy, true_xy = _xy(est_xy, "est_xy"), _xy(true_xy, "true_xy")
    if known_association:
        ids = _ids(est_ids, est_xy.shape[0], "est_ids")
        if ids.size and (ids.min() < 0 or ids.max() >= true_xy.shape[0]):
            raise ValueError(f"est_ids must index true_xy (0..{true_xy.shape[0] - 1}), got {ids.min()}..{ids.max()}")
        d = est_xy - true_xy[ids]
        return np.hypot(d[:, 0], d[:, 1])
    if est_xy.shape[0] and not true_xy.shape[0]:
        raise ValueError("true_xy is empty: no true landmark to compare with")
    d = est_xy[:, None, :] - true_xy[None, :, :]
    return np.hypot(d[..., 0], d[..., 1]).min(axis=1, initial=np.inf)


def true_landmark_errors(est_xy, est_ids, true_xy, which, known_association: bool) -> np.ndarray:
    """Distance ``(len(which),)`` from each true landmark ``true_xy[which]`` to the map's estimate of it.

    Known association: the estimate with that id (``inf`` when the map has none). Otherwise the nearest
    map landmark (``inf`` when the map is empty).
    """
    est_xy, true_xy = _xy(est_xy, "est_xy"), _xy(true_xy, "true_xy")
    which = np.asarray(which, dtype=np.int64).reshape(-1)
    if which.size and (which.min() < 0 or which.max() >= true_xy.shape[0]):
        raise ValueError(f"which must index true_xy (0..{true_xy.shape[0] - 1})")
    truth = true_xy[which]
    if known_association:
        ids = _ids(est_ids, est_xy.shape[0], "est_ids")
        out = np.full(which.size, np.inf)
        row = {int(i): k for k, i in enumerate(ids)}  # the last estimate of a repeated id wins
        for j, i in enumerate(which):
            k = row.get(int(i))
            if k is not None:
                out[j] = np.hypot(*(est_xy[k] - truth[j]))
        return out
    d = truth[:, None, :] - est_xy[None, :, :]
    return np.hypot(d[..., 0], d[..., 1]).min(axis=1, initial=np.inf)
