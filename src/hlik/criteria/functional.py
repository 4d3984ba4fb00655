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


def relative_errors(
    tcp_pos: np.ndarray, tcp_rot: np.ndarray, target_pos: np.ndarray, target_rot: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """fPOS^off and fORI^off (paper Eqs. 3-4): how far the right hand is from where the target's
    relative pose of the hands puts it, seen from the robot's left hand.

    Args:
        tcp_pos, target_pos: (..., 2, 3) robot and target TCP positions (0 = left, 1 = right).
        tcp_rot, target_rot: (..., 2, 3, 3) orientations.

    Returns:
        (...,) position offsets in metres and (...,) orientation offsets in radians.
    """
    rel_rot = np.swapaxes(target_rot[..., 0, :, :], -1, -2) @ target_rot[..., 1, :, :]
    rel_pos = np.einsum(
        "...ji,...j->...i", target_rot[..., 0, :, :], target_pos[..., 1, :] - target_pos[..., 0, :]
    )
    right = tcp_pos[..., 0, :] + np.einsum("...ij,...j->...i", tcp_rot[..., 0, :, :], rel_pos)
    return (
        position_error(right, tcp_pos[..., 1, :]),
        rotation_angle(tcp_rot[..., 0, :, :] @ rel_rot, tcp_rot[..., 1, :, :]),
    )
