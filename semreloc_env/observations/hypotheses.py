"""Position hypotheses of a particle belief, and where a wrapper gets them from.

:func:`cluster_hypotheses` is a stand-in for the relocalizer's own hypothesis list
(``info["belief"]["hypotheses"]``, :class:`filters.localization.belief.Belief`): same format,
same clustering rule as the belief's ``n_clusters`` (8-connected components of occupied
``bin_m`` x ``bin_m`` position bins, keeping those with weight >= ``min_weight``).
:func:`hypotheses_of` takes the filter's list when the ``info`` carries it and falls back to
:func:`cluster_hypotheses` over ``env.unwrapped.mcl`` otherwise, so wrappers switch over
without a change once the relocalizer publishes hypotheses.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from filters.pose import wrap_angle


def cluster_hypotheses(
    poses: np.ndarray, weights: np.ndarray, bin_m: float = 0.5, min_weight: float = 0.02
) -> list[dict]:
    """Hypotheses of a weighted particle set, sorted by weight (descending).

    Args:
        poses: ``(N, 3)`` particle poses ``(x m, y m, theta rad)``.
        weights: ``(N,)`` non-negative weights (normalised here).
        bin_m: position bin edge, metres.
        min_weight: components lighter than this are dropped (stray particles).

    Returns:
        list of ``{"weight": float, "mean": [x, y, theta], "cov": 3x3 list, "n_particles": int}``;
        ``weight`` is the component's share of the total weight, ``mean`` its weighted mean
        (circular in theta), ``cov`` its covariance with wrapped heading residuals.
        Never empty: if every component is lighter than ``min_weight`` the heaviest is kept.

    Raises:
        ValueError: bad shapes, no particles, or weights that are negative, non-finite or all zero.
    """
    p = np.asarray(poses, dtype=np.float64)
    w = np.asarray(weights, dtype=np.float64).reshape(-1)
    if p.ndim != 2 or p.shape[1] != 3 or p.shape[0] == 0:
        raise ValueError(f"poses must have shape (N, 3) with N >= 1, got {p.shape}")
    if w.shape != (p.shape[0],):
        raise ValueError(f"weights must have shape ({p.shape[0]},), got {w.shape}")
    if not np.all(np.isfinite(w)) or np.any(w < 0) or w.sum() <= 0:
        raise ValueError("weights must be finite, non-negative and not all zero")
    if not (np.isfinite(bin_m) and bin_m > 0):
        raise ValueError(f"bin_m must be positive, got {bin_m!r}")
    w = w / w.sum()
    ix = np.floor(p[:, 0] / bin_m).astype(np.int64)
    iy = np.floor(p[:, 1] / bin_m).astype(np.int64)
    ix -= ix.min()
    iy -= iy.min()
    shape = (int(iy.max()) + 1, int(ix.max()) + 1)
    if shape[0] * shape[1] > 4_000_000:  # absurdly spread cloud: coarser bins
        return cluster_hypotheses(p, w, bin_m * 4.0, min_weight)
    occupied = np.zeros(shape, dtype=bool)
    occupied[iy, ix] = True
    labels, n_comp = ndimage.label(occupied, structure=np.ones((3, 3), dtype=bool))
    comp = labels[iy, ix] - 1  # component of every particle
    mass = np.bincount(comp, weights=w, minlength=n_comp)
    order = np.argsort(-mass, kind="stable")
    keep = [int(c) for c in order if mass[c] >= min_weight - 1e-12] or [int(order[0])]
    out = []
    for c in keep:
        sel = comp == c
        pc, wc = p[sel], w[sel] / mass[c]
        mx, my = float(wc @ pc[:, 0]), float(wc @ pc[:, 1])
        mth = float(wrap_angle(np.arctan2(wc @ np.sin(pc[:, 2]), wc @ np.cos(pc[:, 2]))))
        res = np.stack([pc[:, 0] - mx, pc[:, 1] - my, wrap_angle(pc[:, 2] - mth)], axis=1)
        cov = (res * wc[:, None]).T @ res
        out.append(
            {
                "weight": float(mass[c]),
                "mean": [mx, my, mth],
                "cov": [[float(v) for v in row] for row in 0.5 * (cov + cov.T)],
                "n_particles": int(sel.sum()),
            }
        )
    return out


def hypotheses_of(env, info: dict) -> list[dict]:
    """The belief's hypotheses: ``info["belief"]["hypotheses"]`` if the env publishes them, else
    :func:`cluster_hypotheses` of ``env.unwrapped.mcl``'s particles (the belief, not the truth)."""
    published = info.get("belief", {}).get("hypotheses")
    if published is not None:
        return list(published)
    mcl = env.unwrapped.mcl
    return cluster_hypotheses(mcl.poses, mcl.weights)
