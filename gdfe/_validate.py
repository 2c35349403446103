"""Input checks shared by the public functions: each names the argument and what came."""

from __future__ import annotations

import numbers

import numpy as np


def check_positive(name, value):
    """Return ``value`` as float (array) if every entry is finite and > 0, else raise ValueError."""
    arr = _as_float(name, value)
    if not np.all(np.isfinite(arr)) or np.any(arr <= 0):
        raise ValueError(f"{name}: expected a positive finite number, got {_show(value)}")
    return arr if arr.ndim else float(arr)


def check_ratio(name, value):
    """A contraction ratio: finite and in (0, 1]."""
    arr = _as_float(name, value)
    if not np.all(np.isfinite(arr)) or np.any(arr <= 0) or np.any(arr > 1):
        raise ValueError(f"{name}: expected a contraction ratio in (0, 1], got {_show(value)}")
    return arr if arr.ndim else float(arr)


def check_int(name, value, minimum=1):
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise TypeError(f"{name}: expected an integer >= {minimum}, got {value!r}")
    if value < minimum:
        raise ValueError(f"{name}: expected an integer >= {minimum}, got {value}")
    return int(value)


def _as_float(name, value):
    if isinstance(value, (str, bytes)) or value is None:
        raise TypeError(f"{name}: expected a number, got {value!r}")
    try:
        return np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise TypeError(f"{name}: expected a number, got {value!r}") from None


def _show(value):
    arr = np.asarray(value, dtype=float)
    if arr.ndim == 0:
        return f"{float(arr):g}"
    bad = arr[~np.isfinite(arr) | (arr <= 0)] if arr.size else arr
    return f"an array containing {bad.flat[0]:g}" if bad.size else "an array"
