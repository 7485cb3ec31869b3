"""Pure-NumPy reference of the likelihood-field measurement model.

The same model as `filters.localization.likelihood_field` (read its docstring for the
maths), written as plain array code and computed from the *distance fields*
rather than from the precomputed ``log p`` tables, so it checks the tables as
well as the numba kernel. It is slow (it builds ``(N, B)`` temporaries and
evaluates ``log p`` per end point) and exists for tests and the benchmark.

Beam selection (`LikelihoodFieldModel.beams`) is shared with the fast path:
it is part of the model's definition, not of the hot loop.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # annotations only: likelihood_field imports this module for its numpy backend
    from filters.localization.likelihood_field import BeamSet, LikelihoodFieldModel
    from filters.robot_data.scans import LaserScan, SemanticScan


def log_likelihood_terms_reference(
    model: LikelihoodFieldModel, poses: np.ndarray, beams: BeamSet
) -> tuple[np.ndarray, np.ndarray]:
    """``(lidar_ll (N,), semantic_ll (N,))`` for ``poses (N, 3)`` and prepared ``beams``."""
    p = np.asarray(poses, dtype=np.float64)
    ll_l, ll_s = _field_terms(model, p, beams)
    return ll_l, ll_s + negative_evidence_reference(model, p, beams)


def _cells(model: LikelihoodFieldModel, p: np.ndarray, lx: np.ndarray, ly: np.ndarray):
    """``(row, col, inside)`` ``(N, B)`` of robot-frame points ``lx, ly`` (metres) seen from poses ``p``."""
    grid = model.grid
    h, w = grid.shape
    ox, oy = grid.origin_xy_m
    inv_res = 1.0 / grid.resolution_m
    x, y = p[:, 0:1], p[:, 1:2]
    c, s = np.cos(p[:, 2:3]), np.sin(p[:, 2:3])
    lu, lv = lx[None, :] * inv_res, ly[None, :] * inv_res  # robot-frame points, cells
    fx = (x - ox) * inv_res + (c * lu - s * lv)  # (N, B) points in cell units
    fy = (y - oy) * inv_res + (s * lu + c * lv)
    inside = (fx >= 0.0) & (fx < w) & (fy >= 0.0) & (fy < h)
    col = np.where(inside, fx, 0.0).astype(np.int64)  # truncation == floor for fx >= 0
    row = np.where(inside, fy, 0.0).astype(np.int64)
    return row, col, inside


def negative_evidence_reference(model: LikelihoodFieldModel, poses: np.ndarray, beams: BeamSet) -> np.ndarray:
    """``(N,)`` negative evidence (`NegativeEvidenceConfig`) from the distance fields, without tables."""
    p = np.asarray(poses, dtype=np.float64)
    n = p.shape[0]
    if n == 0 or beams.n_negative == 0:
        return np.zeros(n)
    row, col, inside = _cells(model, p, beams.nx, beams.ny)
    d = model.object_distance_m[row, col]
    q = np.where(inside, model.negative_config.log_q(d), 0.0)  # off the map: no object
    per_beam = np.minimum(np.minimum.reduceat(q, beams.n_starts[:-1], axis=1), 0.0)
    return per_beam.sum(axis=1)


def _field_terms(model: LikelihoodFieldModel, p: np.ndarray, beams: BeamSet) -> tuple[np.ndarray, np.ndarray]:
    n = p.shape[0]
    if n == 0 or beams.lx.size == 0:
        return np.zeros(n), np.zeros(n)
    row, col, inside = _cells(model, p, beams.lx, beams.ly)
    t = np.broadcast_to(beams.table[None, :], row.shape)
    dist = model.distance_fields_m[t, row, col]
    logp = np.empty(row.shape)
    for field in np.unique(beams.table):
        cfg = model.config_of(int(field))
        rmax = beams.lidar_range_max_m if field == 0 else beams.semantic_range_max_m
        sel = t == field
        d = np.where(inside[sel], dist[sel], cfg.max_dist_m)  # off the map: the floor
        logp[sel] = cfg.log_p(d, rmax)
    nl = beams.n_lidar
    return logp[:, :nl].sum(axis=1), logp[:, nl:].sum(axis=1)


def log_likelihood_reference(
    model: LikelihoodFieldModel, poses: np.ndarray, lidar: LaserScan | None, semantic: SemanticScan | None = None
) -> np.ndarray:
    """``(N,)`` total log-likelihood, as `LikelihoodFieldModel.log_likelihood`."""
    ll_l, ll_s = log_likelihood_terms_reference(model, poses, model.beams(lidar, semantic))
    return ll_l + ll_s
