"""RelaxedIK's groove loss (paper Sec. IV-A) and the curvatures the SLSQP preconditioner reads."""

from __future__ import annotations

import numpy as np

GROOVE_C, GROOVE_R = 0.1, 10.0  # the paper's c and r (Sec. IV-A)


def groove(
    x: float | np.ndarray, c: float = GROOVE_C, r: float = GROOVE_R, s: float = 0.0, d: int = 2, g: int = 2
) -> tuple[float | np.ndarray, float | np.ndarray]:
    """RelaxedIK's groove loss ``l = -exp(-(x - s)^d / (2 c^2)) + r (x - s)^g`` and dl/dx.

    The paper's form (Sec. IV-A) with n = 1; the defaults are its s = 0, c = 0.1, r = 10, d = g = 2.
    ``x`` is a scalar or an array (elementwise).
    """
    y = x - s
    bump = np.exp(-(y**d) / (2.0 * c * c))
    return -bump + r * y**g, bump * d * y ** (d - 1) / (2.0 * c * c) + r * g * y ** (g - 1)


def groove_curvature(x: np.ndarray, c: float = GROOVE_C, r: float = GROOVE_R) -> np.ndarray:
    """d²l/dx² of :func:`groove` with d = g = 2 at ``x``, floored at the quadratic part's 2r.

    The floor keeps the estimate positive past the bump's inflection (|x| > c)."""
    bump = np.exp(-(x**2) / (2.0 * c * c))
    return np.maximum(bump * (1.0 - x**2 / (c * c)) / (c * c), 0.0) + 2.0 * r


def groove_secant(x: float, c: float = GROOVE_C, r: float = GROOVE_R) -> float:
    """dl/dx / x of :func:`groove` with d = g = 2 at ``x``, its limit l''(0) at 0: the curvature of
    ``l(|e|)`` across the direction of e."""
    return float(np.exp(-(x**2) / (2.0 * c * c)) / (c * c) + 2.0 * r)
