"""Functional criteria: how well the robot TCPs follow their targets (paper Sec. V).

fPOS is the Euclidean distance in metres, fORI the rotation angle in radians between the robot's
and the target hand pose, ``d(Ra, Rb) = arccos((tr(Ra^T Rb) - 1) / 2)`` (formulas.md §0); fPOS^off
and fORI^off the same for the right hand against where the target's relative pose of the hands puts
it (Eqs. 3-4). As terms (:class:`fPOS` ...) they are what the solvers track; their x0 depend on the
scenario (:data:`hlik.criteria.unified.FUNCTIONAL_X0`).
"""

from __future__ import annotations

import numpy as np

from hlik.criteria.base import Criterion, Sample, block_norm_cost, block_norm_gradient
from hlik.util.errors import SettingsError
from hlik.util.spatial import rotation_angle, rotation_vector, skew


def position_error(pos: np.ndarray, target: np.ndarray) -> np.ndarray:
    """fPOS: (...,) distances between (..., 3) positions and targets, metres."""
    return np.linalg.norm(pos - target, axis=-1)


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


def relative_target(sample: Sample) -> tuple[np.ndarray, np.ndarray]:
    """The targets' right hand seen from their left hand: positions (F, 3) and rotations (F, 3, 3)."""
    rot_l = sample.target_rot[:, 0]
    rel_pos = np.einsum("fji,fj->fi", rot_l, sample.target_pos[:, 1] - sample.target_pos[:, 0])
    return rel_pos, np.swapaxes(rot_l, -1, -2) @ sample.target_rot[:, 1]


class fPOS(Criterion):  # noqa: N801 - the paper's name
    """Both TCPs to their target positions; e (F, 6) in m, h the mean distance over the hands."""

    name, functional = "fPOS", True
    sites, parts, part_form = (3,), 2, "norm"

    def residual(self, state, sample):
        return (state.tcp - sample.target_pos).reshape(len(state.q), 6)

    def jacobian(self, state, sample):
        return state.jac[:, :, 3, :3].reshape(len(state.q), 6, -1)

    def cost(self, e):
        return block_norm_cost(e, 2)

    def cost_gradient(self, e):
        return block_norm_gradient(e, 2)


class fORI(Criterion):  # noqa: N801
    """Both TCPs to their target orientations: rotation vectors of R R*^T (rad); h the mean angle."""

    name, functional = "fORI", True
    sites, parts, part_form = (3,), 2, "norm"
    exact_jacobian = False  # first order: exact at the target

    def residual(self, state, sample):
        err = rotation_vector(state.tcp_rot @ np.swapaxes(sample.target_rot, -1, -2))
        return err.reshape(len(state.q), 6)

    def jacobian(self, state, sample):
        # the world-frame rotation vector moves with the angular velocity (first order)
        return state.jac[:, :, 3, 3:].reshape(len(state.q), 6, -1)

    cost, cost_gradient = fPOS.cost, fPOS.cost_gradient


def _right_offset(state, sample: Sample) -> np.ndarray:
    """(F, 3) where the target's relative pose puts the right hand, from the robot's left TCP."""
    rel_pos, _ = relative_target(sample)
    return np.einsum("fij,fj->fi", state.tcp_rot[:, 0], rel_pos)


class fPOS_off(Criterion):  # noqa: N801
    """Paper Eq. 3: t_left + R_left t_rel - t_right (m); h its norm."""

    name, functional = "fPOS_off", True
    sites, part_form = (3,), "norm"

    def residual(self, state, sample):
        return state.tcp[:, 0] + _right_offset(state, sample) - state.tcp[:, 1]

    def jacobian(self, state, sample):
        offset = _right_offset(state, sample)
        jac = state.jac[:, :, 3]  # (F, 2, 6, n)
        # d(R_l t_rel) = omega_l x (R_l t_rel) = -[R_l t_rel]x omega_l
        return jac[:, 0, :3] - skew(offset) @ jac[:, 0, 3:] - jac[:, 1, :3]

    def cost(self, e):
        return block_norm_cost(e, 1)

    def cost_gradient(self, e):
        return block_norm_gradient(e, 1)


class fORI_off(Criterion):  # noqa: N801
    """Paper Eq. 4: rotation vector of (R_left R_rel) R_right^T (rad); h its norm (the angle)."""

    name, functional = "fORI_off", True
    sites, part_form = (3,), "norm"
    exact_jacobian = False

    def residual(self, state, sample):
        _, rel_rot = relative_target(sample)
        return rotation_vector(state.tcp_rot[:, 0] @ rel_rot @ np.swapaxes(state.tcp_rot[:, 1], -1, -2))

    def jacobian(self, state, sample):
        jac = state.jac[:, :, 3, 3:]
        return jac[:, 0] - jac[:, 1]

    cost, cost_gradient = fPOS_off.cost, fPOS_off.cost_gradient


# the terms on the hands' pose (their targets, or the relative pose of the hands)
HAND_TERMS = (fPOS, fORI, fPOS_off, fORI_off)


def target_terms(scenario: str) -> tuple[Criterion, Criterion]:
    """The position and orientation terms ``scenario`` tracks: the TCP poses (``pose``) or the
    relative pose of the hands (``relative``, paper Eqs. 3-4)."""
    if scenario == "pose":
        return fPOS(), fORI()
    if scenario == "relative":
        return fPOS_off(), fORI_off()
    raise SettingsError(f"scenario must be 'pose' or 'relative', got {scenario!r}")
