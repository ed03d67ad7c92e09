"""Scalar arguments cast to one Python type before they reach a compiled kernel.

numba compiles a fresh specialisation of a kernel for every new combination of argument
types (11-70 s on the lead's 2-core machine), so ``emd(x, 8, sd_threshold=0)`` with an int
threshold, or a numpy ``int32`` iteration cap, would otherwise pay a compile in the middle
of a run. The public functions of this package pass their scalars through these casts and
their arrays through ``np.ascontiguousarray(..., dtype=...)``.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["as_count", "as_real"]


def as_count(name: str, value: object) -> int:
    """``value`` as a Python ``int``: integers of any kind and integral floats are accepted.

    Raises
    ------
    TypeError
        For a bool or a value that is not a real number.
    ValueError
        For a float that is not integral (NaN and infinities included).
    """
    if isinstance(value, (bool, np.bool_)) or not isinstance(
        value, (int, float, np.integer, np.floating)
    ):
        raise TypeError(f"{name} must be an integer, got {value!r}")
    if isinstance(value, (int, np.integer)):
        return int(value)
    if not (math.isfinite(value) and value == math.floor(value)):
        raise ValueError(f"{name} must be an integer, got {value!r}")
    return int(value)


def as_real(name: str, value: object) -> float:
    """``value`` as a Python ``float`` (integers and numpy scalars included).

    Raises
    ------
    TypeError
        For a bool or a value that is not a real number.
    """
    if isinstance(value, (bool, np.bool_)) or not isinstance(
        value, (int, float, np.integer, np.floating)
    ):
        raise TypeError(f"{name} must be a real number, got {value!r}")
    return float(value)
