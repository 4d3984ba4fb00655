"""Functional criteria: how well the robot TCPs follow their targets (paper Sec. V).

fPOS is the Euclidean distance in metres, fORI the rotation angle in radians between the robot's
and the target hand pose, ``d(Ra, Rb) = arccos((tr(Ra^T Rb) - 1) / 2)`` (formulas.md §0).
"""

from __future__ import annotations

import numpy as np


def position_error(pos: np.ndarray, target: np.ndarray) -> np.ndarray:
    """fPOS: (...,) distances between (..., 3) positions and targets, metres."""
    return np.linalg.norm(pos - target, axis=-1)


def rotation_angle(rot_a: np.ndarray, rot_b: np.ndarray) -> np.ndarray:
    """fORI: (...,) angles of ``rot_a^T rot_b`` for (..., 3, 3) rotations, radians in [0, pi]."""
    rel = np.swapaxes(rot_a, -1, -2) @ rot_b
    # atan2 of sine and cosine stays exact near 0, where arccos of the trace loses half the digits
    axis = np.stack(
        [rel[..., 2, 1] - rel[..., 1, 2], rel[..., 0, 2] - rel[..., 2, 0], rel[..., 1, 0] - rel[..., 0, 1]],
        -1,
    )
    cos = (np.trace(rel, axis1=-2, axis2=-1) - 1.0) / 2.0
    return np.arctan2(np.linalg.norm(axis, axis=-1) / 2.0, cos)
