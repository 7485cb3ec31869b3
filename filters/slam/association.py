"""Data-association settings and the small numeric helpers the SLAM filters share.

Association is maximum likelihood with two gates on the normalised innovation
squared ``NIS = v^T S^-1 v`` (2 degrees of freedom), as in Bailey's EKF-SLAM:
the candidate with the smallest ``NIS + log det S`` is chosen; it is a match
if its ``NIS < gate_associate``; if every existing landmark has
``NIS > gate_new`` the observation starts a new landmark; in between the
observation is ambiguous and is ignored. With ``association="known"`` the
caller's landmark ids decide instead.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from filters.pose import wrap_angle

ASSOCIATIONS = ("ml", "known")


@dataclass(frozen=True)
class AssociationConfig:
    """How observations are matched to landmarks.

    mode: ``"ml"`` (maximum likelihood with gates) or ``"known"`` (ids given with each scan).
    gate_associate: NIS below which the ML candidate is accepted (default: chi^2_2 99 %, 9.21).
    gate_new: NIS above which (for every landmark) a new landmark is made (default 25, Bailey's GATE_AUGMENT).
    gate_first: False (every registered env and reproduction, so that their runs stay as they were): the candidate
        of least ``NIS + log det S`` over all landmarks is chosen, then gated, so a tight landmark outside the gate
        can win and the observation is ignored though another landmark lies inside it (an outside audit). True: the
        choice is among the landmarks inside the gate only, as Bailey's ``data_associate.m``.
    """

    mode: str = "ml"
    gate_associate: float = 9.21
    gate_new: float = 25.0
    gate_first: bool = False

    def __post_init__(self) -> None:
        if not isinstance(self.gate_first, (bool, np.bool_)):
            raise ValueError(f"AssociationConfig.gate_first must be a bool, got {self.gate_first!r}")
        object.__setattr__(self, "gate_first", bool(self.gate_first))
        if self.mode not in ASSOCIATIONS:
            raise ValueError(f"association mode must be one of {ASSOCIATIONS}, got {self.mode!r}")
        if not (0 < self.gate_associate <= self.gate_new < math.inf):
            raise ValueError(
                f"need 0 < gate_associate <= gate_new < inf, got {self.gate_associate}, {self.gate_new} "
                "(an infinite gate_new would never make a landmark once one exists)"
            )


def ml_scores(nis: np.ndarray, logdet: np.ndarray, config: AssociationConfig) -> np.ndarray:
    """The score whose least value picks the maximum-likelihood candidate: ``NIS + log det S``, and with
    ``config.gate_first`` inf outside the association gate (so the choice is among the gated candidates)."""
    score = nis + logdet
    return np.where(nis < config.gate_associate, score, np.inf) if config.gate_first else score


def inv2(s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Inverse and determinant of a stack of 2x2 matrices ``(..., 2, 2)`` in closed form."""
    a, b, c, d = s[..., 0, 0], s[..., 0, 1], s[..., 1, 0], s[..., 1, 1]
    det = a * d - b * c
    inv = np.empty_like(s)
    inv[..., 0, 0] = d / det
    inv[..., 0, 1] = -b / det
    inv[..., 1, 0] = -c / det
    inv[..., 1, 1] = a / det
    return inv, det


def innovation(z: np.ndarray, z_hat: np.ndarray) -> np.ndarray:
    """``z - z_hat`` with the bearing difference wrapped to ``[-pi, pi)``."""
    v = z - z_hat
    v[..., 1] = wrap_angle(v[..., 1])
    return v


def nis_and_logdet(v: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``v^T S^-1 v`` and ``log det S`` for stacks ``v (..., 2)`` and ``S (..., 2, 2)``."""
    s_inv, det = inv2(s)
    nis = np.einsum("...i,...ij,...j->...", v, s_inv, v)
    return nis, np.log(det)


def gauss_logpdf(v: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Log density of ``N(0, S)`` at ``v`` for 2D stacks."""
    nis, logdet = nis_and_logdet(v, s)
    return -0.5 * nis - 0.5 * logdet - np.log(2.0 * np.pi)
