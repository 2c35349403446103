"""Input checks shared by the reference FEM (messages name the argument, the expectation and the value)."""

from __future__ import annotations

import math

import numpy as np


def positive(name: str, value) -> float:
    """Return ``value`` as a float, or raise ``ValueError`` unless it is finite and > 0."""
    x = _real(name, value)
    if not x > 0.0:
        raise ValueError(f"{name} must be a positive number, got {value!r}")
    return x


def poisson(name: str, value) -> float:
    """Return a Poisson's ratio, or raise ``ValueError`` unless -1 < value < 0.5."""
    x = _real(name, value)
    if not -1.0 < x < 0.5:
        raise ValueError(f"{name} must satisfy -1 < {name} < 0.5 (Poisson's ratio), got {value!r}")
    return x


def eigenstrain(name: str, value) -> float:
    """Return an eigenstrain component, or raise ``ValueError`` unless it is > -1."""
    x = _real(name, value)
    if not x > -1.0:
        raise ValueError(
            f"{name} must be greater than -1 (a free stretch 1 + {name} > 0), got {value!r}"
        )
    return x


def positive_int(name: str, value, minimum: int = 1) -> int:
    """Return ``value`` as an int, or raise ``ValueError`` unless it is an integer >= ``minimum``."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")
    if value < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


def choice(name: str, value, options) -> str:
    """Return ``value`` if it is one of ``options``, else raise ``ValueError`` listing them."""
    if value not in options:
        raise ValueError(f"{name} must be one of {sorted(options)}, got {value!r}")
    return value


def _real(name: str, value) -> float:
    if isinstance(value, bool):
        raise ValueError(f"{name} must be a real number, got {value!r}")
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a real number, got {value!r}") from None
    if not math.isfinite(x):
        raise ValueError(f"{name} must be a finite number, got {value!r}")
    return x
