"""Weight transforms applied to normalised importance weights before resampling.

A transform maps normalised weights ``(N,)`` to normalised weights ``(N,)``.
The resampler then draws ancestors from the transformed weights.

* `identity` -- plain particle filter.
* `woc` -- the weight-optimisation-combination step of paper 000 (Eq. 7)::

      psi_i = (K - 1) / K * w_i + mean(w) / K,     1 <= K <= inf

  ``K = 1`` gives uniform weights, ``K = inf`` the plain weights. Low-weight
  particles get more copies, which keeps the particle set diverse. Note the
  paper resamples on ``psi`` without an importance correction ``w / psi``;
  so do we, as the paper does.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from filters.smc.resampling import normalise_weights


def identity(weights) -> np.ndarray:
    """The weights, normalised to sum to 1."""
    return normalise_weights(weights)


def woc(weights, K: float) -> np.ndarray:
    """Paper 000 Eq. 7: ``(K-1)/K * w + mean(w)/K``, normalised. ``K >= 1``; ``K = inf`` -> plain weights.

    Raises ValueError for ``K < 1`` or NaN.
    """
    K = float(K)
    if not K >= 1.0:
        raise ValueError(f"WOC scaling factor K must satisfy 1 <= K <= inf, got {K}")
    w = normalise_weights(weights)
    if np.isinf(K):
        return w
    psi = (K - 1.0) / K * w + w.mean() / K
    return psi / psi.sum()


@dataclass(frozen=True)
class WOC:
    """`woc` with a fixed ``K`` as a callable ``weights -> weights`` (a filter config value)."""

    K: float = 5.0

    def __post_init__(self) -> None:
        if not float(self.K) >= 1.0:
            raise ValueError(f"WOC scaling factor K must satisfy 1 <= K <= inf, got {self.K}")

    def __call__(self, weights) -> np.ndarray:
        return woc(weights, self.K)


WeightTransform = Callable[[np.ndarray], np.ndarray]


def get_weight_transform(name: str, K: float = 5.0) -> WeightTransform:
    """``"identity"`` or ``"woc"`` (with scaling factor ``K``) as a callable."""
    if name == "identity":
        return identity
    if name == "woc":
        return WOC(K)
    raise ValueError(f"unknown weight transform {name!r}; choose 'identity' or 'woc'")
