"""Angle differences and the cross product the criteria share. Limitless joints compare by angular
distance (paper, footnote 1)."""

from __future__ import annotations

import numpy as np


def wrap(x: np.ndarray) -> np.ndarray:
    """Angles wrapped to [-pi, pi)."""
    return (np.asarray(x) + np.pi) % (2.0 * np.pi) - np.pi


def joint_difference(a: np.ndarray, b: np.ndarray, unlimited: np.ndarray) -> np.ndarray:
    """``a - b`` per joint (..., k), wrapped where ``unlimited`` (k,) is True."""
    d = np.asarray(a) - np.asarray(b)
    return np.where(unlimited, wrap(d), d)


def cross(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """u x v (..., 3) over the last axis, broadcast; np.cross costs ten times more on the criteria's
    small arrays."""
    return np.stack(
        [
            u[..., 1] * v[..., 2] - u[..., 2] * v[..., 1],
            u[..., 2] * v[..., 0] - u[..., 0] * v[..., 2],
            u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0],
        ],
        axis=-1,
    )
