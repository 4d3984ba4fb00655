"""Angle differences the criteria share. Limitless joints compare by angular
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
