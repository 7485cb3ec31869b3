"""What counts as a number in argument checks: Python and NumPy scalars, never a bool.

``True`` is an ``int`` to Python and ``np.float32(0.5)`` is not a ``float``; configs and
constructors across the package check their arguments with these two predicates so that both
cases are treated alike everywhere.
"""

from __future__ import annotations

import numpy as np


def is_int(v) -> bool:
    """``v`` is a Python or NumPy integer, not a bool."""
    return isinstance(v, (int, np.integer)) and not isinstance(v, (bool, np.bool_))


def is_real(v) -> bool:
    """``v`` is a Python or NumPy integer or float, not a bool (NaN and inf included)."""
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, (bool, np.bool_))
