"""Arrays a value object owns: read-only, and no one else's buffer.

Scans and maps keep the arrays they were built from; a caller that reuses its buffer for the next
reading (a ROS callback filling one array) must not change a scan or map already built from it.
"""

from __future__ import annotations

import numpy as np


def frozen_array(values, dtype) -> np.ndarray:
    """``values`` as a read-only array of ``dtype``: a copy, unless ``values`` already is a read-only
    array of ``dtype`` that is not a view of a writable one (as this function's results are), so a
    caller that reuses its buffer cannot change what was built from it. (NumPy lets the owner of a
    read-only array make it writable again; nothing in this package does.)"""
    if isinstance(values, np.ndarray) and values.dtype == dtype and not values.flags.writeable:
        base = values.base
        if base is None or (isinstance(base, np.ndarray) and not base.flags.writeable and base.base is None):
            return values
    out = np.array(values, dtype=dtype)
    out.setflags(write=False)
    return out
