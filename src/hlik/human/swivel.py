"""The swivel angle Ψ of an arm (the elbow's elevation about the shoulder -> wrist axis, Kim et
al.'s and Zanchettin's elbow angle; formulas.md §1.1) from its joint centres: the same geometry for
the human (:mod:`hlik.problem.reference`, :mod:`hlik.posture`) and the robot (EEA's residual and
gradients in :mod:`hlik.criteria.eea`).

Ψ = 0 has the elbow straight down (the plane of the arm axis and the vertical); it grows as the
elbow lifts outward, the left arm mirrored so that both arms read alike.
"""

from __future__ import annotations

import numpy as np

TWO_PI = 2.0 * np.pi
_SINGULAR = 1e-6  # relative size below which the swivel angle is undefined
_UP = np.array([0.0, 0.0, 1.0])
_CROSS_UP = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]])  # v @ _CROSS_UP = v x up
_SIDE_SIGN = np.array([-1.0, 1.0])  # left Ψ = -Ψ_raw, right Ψ = Ψ_raw


def unit(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """v / |v| and |v| over the last axis (NaN for 0: call within np.errstate)."""
    norm = np.sqrt(np.einsum("...i,...i->...", v, v))
    return v / norm[..., None], norm


def swivel_parts(shoulder: np.ndarray, elbow: np.ndarray, wrist: np.ndarray):
    """Raw (unmirrored) Ψ and everything its gradient needs; arrays (..., 2[, 3])."""
    a = np.asarray(wrist, float) - np.asarray(shoulder, float)
    b = np.asarray(elbow, float) - np.asarray(shoulder, float)
    with np.errstate(invalid="ignore", divide="ignore"):
        n, a_norm = unit(a)
        c = n[..., 2]  # cos of the axis' angle to the vertical
        r, sigma = unit(_UP - c[..., None] * n)
        t = (n @ _CROSS_UP) / sigma[..., None]  # n x r, as n x n = 0
        x = np.einsum("...i,...i->...", b, r)
        y = np.einsum("...i,...i->...", b, t)
        z = np.einsum("...i,...i->...", b, n)
        eps2 = x**2 + y**2  # squared distance of the elbow from the shoulder -> wrist axis
        scale = a_norm + np.sqrt(np.einsum("...i,...i->...", b, b))
        singular = (sigma < _SINGULAR) | (np.sqrt(eps2) < _SINGULAR * scale) | ~(scale > 0)
        psi_raw = np.where(singular, np.nan, np.arctan2(y, x))
    return psi_raw, singular, n, r, t, x, y, z, eps2, c, sigma, a_norm


def swivel_angle(shoulder: np.ndarray, elbow: np.ndarray, wrist: np.ndarray) -> np.ndarray:
    """Ψ (..., 2) in [0, 2π) from (..., 2, 3) joint centres (arm 0 = left, mirrored); NaN if singular."""
    psi_raw = swivel_parts(shoulder, elbow, wrist)[0]
    return (_SIDE_SIGN * psi_raw) % TWO_PI


def forward_fill(psi: np.ndarray) -> np.ndarray:
    """``psi`` (F, ...) with every NaN replaced by the last valid value along axis 0.

    Leading NaNs take the first valid value; columns without any valid value stay NaN.
    """
    psi = np.array(psi, dtype=float)
    flat = psi.reshape(len(psi), -1)
    for col in flat.T:
        valid = np.flatnonzero(~np.isnan(col))
        if valid.size == 0 or valid.size == len(col):
            continue
        src = np.maximum.accumulate(np.where(np.isnan(col), 0, np.arange(len(col))))
        src[: valid[0]] = valid[0]
        col[:] = col[src]
    return flat.reshape(psi.shape)
