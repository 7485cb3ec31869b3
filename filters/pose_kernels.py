"""Compiled (numba) twins of `filters.pose` for one value, the same bits as the NumPy functions."""

from __future__ import annotations

import numba
import numpy as np

_TWO_PI = 2.0 * np.pi


@numba.njit(cache=True, nogil=True, inline="always")
def wrap_angle_scalar(a):  # pragma: no cover - compiled
    """`filters.pose.wrap_angle` of one float (radians, to ``[-pi, pi)``), bit for bit.

    ``y % 2pi`` (floored modulo) is ``y`` itself when ``0 <= y < 2pi`` (``fmod`` is exact and
    needs no sign fix; a zero becomes ``+0.0`` as in NumPy), so the slow ``fmod`` only runs for
    angles outside ``[-pi, pi)``; particles' headings are almost always inside.
    """
    y = a + np.pi
    if 0.0 < y < _TWO_PI:
        return y - np.pi
    if y == 0.0:
        return 0.0 - np.pi
    return y % _TWO_PI - np.pi
