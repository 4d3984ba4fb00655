"""SOA: Soechting & Flanders' predicted arm posture, SOA_x and SOA_q residuals and Jacobians."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

import hlik
from conftest import ROBOTS
from hlik.criteria.soechting import (
    mmm_angles,
    predict_arm,
    soa_q_cost,
    soa_q_jacobian,
    soa_q_residual,
    soa_q_targets,
    soa_x_cost,
    soa_x_jacobian,
    soa_x_residual,
)
from hlik.human.kinematics import human_model
from hlik.robot.state import arm_lengths, robot_state

MIRROR = np.array([-1.0, 1.0, 1.0])


def unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def hand_prediction(r_cm, chi, psi, l_u, side_sign):
    """The published dark-pointing coefficients evaluated by hand (degrees in, u and f out)."""
    theta = np.radians(-4.0 + 1.10 * r_cm + 0.90 * psi)
    eta = np.radians(13.2 + 0.86 * chi + 0.11 * psi)
    beta = np.radians(39.4 + 0.54 * r_cm - 1.06 * psi)
    alpha = np.radians(-10.0 + 1.08 * chi - 0.35 * psi)
    u = np.array([side_sign * np.sin(theta) * np.sin(eta), np.sin(theta) * np.cos(eta), -np.cos(theta)])
    f = np.array([side_sign * np.sin(beta) * np.sin(alpha), np.sin(beta) * np.cos(alpha), np.cos(beta)])
    s_x = np.pi - np.arctan2(u[1], u[2])
    s_x = s_x - 2 * np.pi if s_x > 1.5 * np.pi else s_x
    return l_u * u, np.array([s_x, -np.arcsin(u[0]), np.arccos(u @ f)])


@pytest.mark.parametrize("direction, chi, psi", [((0.0, 0.0, -1.0), 0.0, -90.0), ((0.0, 1.0, 0.0), 0.0, 0.0)])
def test_predictions_by_hand(direction, chi, psi):
    l_u, l_f = np.array([0.3, 0.3]), np.array([0.25, 0.25])
    shoulder = np.array([[-0.2, 0.1, 1.4], [0.2, 0.1, 1.4]])
    dist = 0.5
    wrist = shoulder + dist * np.array(direction)
    elbow, angles = predict_arm(shoulder, wrist, l_u, l_f)
    r_cm = 100 * 0.6 / 0.55 * dist
    for arm, sign in ((0, -1.0), (1, 1.0)):
        offset, expected = hand_prediction(r_cm, chi, psi, l_u[arm], sign)
        np.testing.assert_allclose(elbow[arm], shoulder[arm] + offset, atol=1e-12)
        np.testing.assert_allclose(angles[arm], expected, atol=1e-12)


def test_angle_conversion_checks():
    hanging = np.array([0.0, 0.0, -1.0])
    forward = np.array([0.0, 1.0, 0.0])
    np.testing.assert_allclose(mmm_angles(hanging, hanging), [0.0, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(mmm_angles(forward, forward), [np.pi / 2, 0.0, 0.0], atol=1e-12)
    # slightly backward upper arm: small negative s_x, not ~2π
    assert mmm_angles(unit(np.array([0.0, -0.1, -1.0])), hanging)[0] == pytest.approx(-np.arctan(0.1))
    assert mmm_angles(forward, hanging)[2] == pytest.approx(np.pi / 2)


def test_angle_conversion_matches_the_mmm_model():
    """(s_x, s_y, e_x) of the MMM model's own upper arm and forearm are its S_x, S_y, E_x joints."""
    model = human_model(1.75)
    data = mujoco.MjData(model)
    rng = np.random.default_rng(0)
    for side, p, sy_range in (("left", "L", (0.0, 1.5)), ("right", "R", (-1.5, 0.0))):
        for _ in range(4):
            want = np.array([rng.uniform(-1.2, 3.1), rng.uniform(*sy_range), rng.uniform(0.0, 2.7)])
            data.qpos[:] = 0.0
            data.qpos[3] = 1.0  # free root at the identity quaternion
            for j, v in zip(("Sx", "Sy", "Ex"), want):
                data.qpos[model.jnt_qposadr[model.joint(f"{p}{j}_joint").id]] = v
            mujoco.mj_kinematics(model, data)
            s, e, w = (data.site_xpos[model.site(f"{side}_{n}").id] for n in ("shoulder", "elbow", "wrist"))
            np.testing.assert_allclose(mmm_angles(unit(e - s), unit(w - e)), want, atol=1e-9)


def test_mirror_symmetry():
    rng = np.random.default_rng(2)
    l_u, l_f = np.array([0.3, 0.3]), np.array([0.25, 0.25])
    shoulder_r = np.array([0.2, 0.0, 1.4]) + rng.normal(scale=0.01, size=(10, 3))
    wrist_r = shoulder_r + rng.uniform([-0.3, 0.0, -0.5], [0.4, 0.5, 0.3], size=(10, 3))
    shoulder = np.stack([shoulder_r * MIRROR, shoulder_r], axis=1)
    wrist = np.stack([wrist_r * MIRROR, wrist_r], axis=1)
    elbow, angles = predict_arm(shoulder, wrist, l_u, l_f)
    np.testing.assert_allclose(elbow[:, 0], elbow[:, 1] * MIRROR, atol=1e-12)
    np.testing.assert_allclose(angles[:, 0], angles[:, 1] * [1.0, -1.0, 1.0], atol=1e-12)


def random_q(robot, rng, k):
    lo = np.where(np.isinf(robot.lower), -np.pi, robot.lower)
    hi = np.where(np.isinf(robot.upper), np.pi, robot.upper)
    return lo + (hi - lo) * rng.uniform(0.05, 0.95, size=(k, robot.dof))


def fd_jacobian(robot, q, residual, h=1e-6):
    n = robot.dof
    steps = np.concatenate([q + h * np.eye(n), q - h * np.eye(n)])
    r = residual(robot_state(robot, steps))
    return np.moveaxis((r[:n] - r[n:]) / (2 * h), 0, -1)


@pytest.mark.parametrize("name", ROBOTS)
def test_soa_jacobians_match_finite_differences(name):
    robot = hlik.load_robot(name)
    l_u, l_f = arm_lengths(robot)
    rng = np.random.default_rng(11)
    q = random_q(robot, rng, 3)
    state = robot_state(robot, q, jacobians=True)
    elbow_pred, angles = predict_arm(state.shoulder, state.wrist, l_u, l_f)
    idx, targets = soa_q_targets(robot, angles)
    jx = soa_x_jacobian(state, l_u)
    jq = soa_q_jacobian(state, idx)
    assert jx.shape == (3, 2, 3, robot.dof) and jq.shape == (3, len(idx), robot.dof)
    for k in range(len(q)):
        fd_x = fd_jacobian(robot, q[k], lambda s, k=k: soa_x_residual(s, elbow_pred[k], l_u))
        np.testing.assert_allclose(jx[k], fd_x, atol=1e-6)
        fd_q = fd_jacobian(robot, q[k], lambda s, k=k: soa_q_residual(robot, s, idx, targets[k : k + 1]))
        np.testing.assert_allclose(jq[k], fd_q, atol=1e-6)
    res_x = soa_x_residual(state, elbow_pred, l_u)
    np.testing.assert_allclose(soa_x_cost(res_x), np.linalg.norm(res_x, axis=-1).mean(-1))
    res_q = soa_q_residual(robot, state, idx, targets)
    assert res_q.shape == (3, len(idx))
    np.testing.assert_allclose(soa_q_cost(res_q), (res_q**2).mean(-1))


@pytest.mark.parametrize("name", ROBOTS)
def test_soa_q_targets_follow_the_mapping(name):
    robot = hlik.load_robot(name)
    rng = np.random.default_rng(3)
    angles = rng.uniform([0.0, -0.5, 0.0], [2.5, 0.5, 2.5], size=(7, 2, 3))
    angles[:, 0, 1] = np.abs(angles[:, 0, 1])  # abduction: positive left, negative right
    angles[:, 1, 1] = -np.abs(angles[:, 1, 1])
    idx, targets = soa_q_targets(robot, angles)
    assert len(idx) == 6 and targets.shape == (7, 6)
    predicted = [f"{p}{j}_joint" for p in "LR" for j in ("Sx", "Sy", "Ex")]
    names = sorted(set(robot.mapping.mmm_joints) | set(predicted))
    mmm = np.zeros((7, len(names)))  # joints the prediction does not cover stay at 0
    mmm[:, [names.index(n) for n in predicted]] = angles.reshape(7, 6)
    mapped = robot.mapping.apply(names, mmm)
    for col, i in enumerate(idx):
        np.testing.assert_allclose(targets[:, col], mapped[robot.joint_names[i]])
    # the residual at the targets themselves is zero
    q = np.tile(robot.home, (7, 1))
    q[:, idx] = targets
    state = robot_state(robot, q[:2])
    np.testing.assert_allclose(soa_q_residual(robot, state, idx, targets[:2]), 0.0, atol=1e-12)
