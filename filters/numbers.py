"""What counts as a number in argument checks: Python and NumPy scalars, never a bool.

``True`` is an ``int`` to Python, ``np.timedelta64`` an integer to NumPy and ``np.float32(0.5)`` is
not a ``float``; configs and constructors across the package check their arguments with these
predicates so that such cases are treated alike everywhere.
"""

from __future__ import annotations

import numbers
import re

import numpy as np

MAX_LENGTH_M = 1e6
"""Largest length (m) the estimators take as a range, a distance or a noise std: no sensor of a mobile robot
measures farther, and the squares of far larger lengths overflow their covariance arithmetic."""


def is_int(v) -> bool:
    """``v`` is a Python or NumPy integer, not a bool nor a ``np.timedelta64`` (which NumPy makes an integer)."""
    return isinstance(v, (int, np.integer)) and not isinstance(v, (bool, np.bool_, np.timedelta64))


def is_real(v) -> bool:
    """``v`` is a real number (``numbers.Real``: Python and NumPy ints and floats among them), not a bool nor a
    ``np.timedelta64`` (NaN and inf included)."""
    return isinstance(v, numbers.Real) and not isinstance(v, (bool, np.bool_, np.timedelta64))


def is_int_dtype(dtype) -> bool:
    """``dtype`` holds integers: a signed or unsigned NumPy integer type, not ``timedelta64``."""
    return np.dtype(dtype).kind in "iu"


_EXPONENT_FORM = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)[eE][-+]?\d+")


def is_exponent_form(v: str) -> bool:
    """``v`` is a number in exponent form (``5e-2``, ``-1e2``, ``1.5E+3``), as a string."""
    return bool(_EXPONENT_FORM.fullmatch(v.strip()))


def yaml_number_hint(v) -> str:
    """A hint for a value YAML 1.1 (PyYAML) read otherwise than a number was meant: a boolean (``no``,
    ``yes``, ``off``, ``on`` are booleans), or a string written in exponent form, which YAML 1.1 reads as a
    number only with a dot and a signed exponent (``1.0e-3``, ``1.0e+3``; ``1e-3`` and ``1.0e3`` are
    strings); "" for anything else. For error messages about YAML files."""
    if isinstance(v, bool):
        return " (a boolean; in a YAML file yes/no, on/off and true/false are booleans: write a number)"
    if not (isinstance(v, str) and is_exponent_form(v)):
        return ""
    return (
        " (YAML reads a number in exponent form as a string unless it has a dot and a signed exponent:"
        " write 1.0e-3 or 1.0e+3)"
    )
