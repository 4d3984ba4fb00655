"""EEA: the swivel angle, its gradients and Jacobian, the Ψ_human predictor and the cost."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import hlik
from hlik.criteria.angles import wrap
from hlik.criteria.eea import (
    EULER,
    SwivelPredictor,
    eea_cost,
    eea_r_target,
    eea_residual,
    swivel_gradient,
    swivel_jacobian,
)
from hlik.human.demo import demo_motion
from hlik.human.kinematics import forward_kinematics
from hlik.human.swivel import forward_fill, swivel_angle
from hlik.robot.state import robot_state

MIRROR = np.array([-1.0, 1.0, 1.0])


@pytest.fixture(scope="module")
def human():
    return forward_kinematics(demo_motion())  # native 25 Hz


def random_q(robot, rng, k):
    lo = np.where(np.isinf(robot.lower), -np.pi, robot.lower)
    hi = np.where(np.isinf(robot.upper), np.pi, robot.upper)
    return lo + (hi - lo) * rng.uniform(0.05, 0.95, size=(k, robot.dof))


@pytest.mark.parametrize("name", ["armar3", "armar6", "dual_panda"])
def test_swivel_jacobian_matches_finite_differences(name):
    robot = hlik.load_robot(name)
    rng = np.random.default_rng(7)
    q = random_q(robot, rng, 6)
    state = robot_state(robot, q, jacobians=True)
    jac = swivel_jacobian(state, cap=np.inf)
    h = 1e-6
    n = robot.dof
    checked = 0
    for k in range(len(q)):
        steps = np.concatenate([q[k] + h * np.eye(n), q[k] - h * np.eye(n)])
        s = robot_state(robot, steps).sites
        psi = swivel_angle(s[:, :, 0], s[:, :, 1], s[:, :, 2])
        fd = (wrap(psi[:n] - psi[n:]) / (2 * h)).T  # (2, n)
        for arm in range(2):
            if np.linalg.norm(jac[k, arm]) > 10.0:  # near a singularity: FD unreliable
                continue
            np.testing.assert_allclose(jac[k, arm], fd[arm], atol=1e-5 * max(1.0, np.abs(fd[arm]).max()))
            checked += 1
    assert checked >= 6


def test_swivel_jacobian_cap():
    robot = hlik.load_robot("dual_panda")
    state = robot_state(robot, random_q(robot, np.random.default_rng(3), 4), jacobians=True)
    full = swivel_jacobian(state, cap=np.inf)
    capped = swivel_jacobian(state, cap=0.1)
    assert np.all(np.linalg.norm(capped, axis=-1) <= 0.1 + 1e-12)
    # capping only rescales: same direction
    cos = np.sum(full * capped, -1) / np.linalg.norm(full, axis=-1) / np.linalg.norm(capped, axis=-1)
    np.testing.assert_allclose(cos, 1.0)


def test_swivel_gradient_matches_finite_differences():
    rng = np.random.default_rng(1)
    pts = [rng.normal(size=(5, 2, 3)) for _ in range(3)]
    grads = swivel_gradient(*pts)
    h = 1e-6
    for which, g in enumerate(grads):
        fd = np.zeros_like(g)
        for axis in range(3):
            plus = [p.copy() for p in pts]
            minus = [p.copy() for p in pts]
            plus[which][..., axis] += h
            minus[which][..., axis] -= h
            fd[..., axis] = wrap(swivel_angle(*plus) - swivel_angle(*minus)) / (2 * h)
        np.testing.assert_allclose(g, fd, atol=1e-6)
    # translation invariance
    np.testing.assert_allclose(sum(grads), 0.0, atol=1e-12)


def test_swivel_conventions():
    shoulder = np.array([[-0.2, 0.0, 1.4], [0.2, 0.0, 1.4]])
    wrist = shoulder + [0.0, 0.5, 0.0]
    below = shoulder + [0.0, 0.25, -0.15]
    outward = shoulder + [[-0.15, 0.25, 0.0], [0.15, 0.25, 0.0]]
    above = shoulder + [0.0, 0.25, 0.15]
    np.testing.assert_allclose(swivel_angle(shoulder, below, wrist), [np.pi, np.pi])
    np.testing.assert_allclose(swivel_angle(shoulder, outward, wrist), [np.pi / 2, np.pi / 2])
    np.testing.assert_allclose(wrap(swivel_angle(shoulder, above, wrist)), [0.0, 0.0], atol=1e-12)
    # singular: stretched arm, or a vertical shoulder -> wrist axis
    assert np.all(np.isnan(swivel_angle(shoulder, shoulder + [0.0, 0.25, 0.0], wrist)))
    assert np.all(np.isnan(swivel_angle(shoulder, below, shoulder + [0.0, 0.0, -0.5])))


def test_swivel_mirror(human):
    s, e, w = human.shoulder[:, 1], human.elbow[:, 1], human.wrist[:, 1]
    pose = [np.stack([p * MIRROR, p], axis=1) for p in (s, e, w)]  # right arm mirrored to the left
    psi = swivel_angle(*pose)
    assert np.all(np.isfinite(psi))
    np.testing.assert_allclose(psi[:, 0], psi[:, 1], atol=1e-12)
    gl = swivel_gradient(*pose)
    for g in gl:
        np.testing.assert_allclose(g[:, 0], g[:, 1] * MIRROR, atol=1e-10)


def test_human_pose_against_itself(human):
    psi = swivel_angle(human.shoulder, human.elbow, human.wrist)
    assert psi.shape == (len(human.shoulder), 2)
    assert np.all((psi >= 0) & (psi < 2 * np.pi))
    res = eea_residual(psi, psi)
    np.testing.assert_array_equal(res, 0.0)
    np.testing.assert_array_equal(eea_cost(res), 0.0)
    # natural postures: outward-down to straight down
    assert np.all((psi > 1.5) & (psi < 3.4))


def test_residual_and_cost():
    res = eea_residual(np.array([0.1, 6.2]), np.array([6.2, 0.1]))
    np.testing.assert_allclose(res, [(0.1 - 6.2 + 2 * np.pi) / np.pi, (6.2 - 0.1 - 2 * np.pi) / np.pi])
    assert eea_cost(res) == pytest.approx(np.mean(np.abs(res)))
    assert np.isnan(eea_cost(np.array([0.2, np.nan])))


def test_eea_r_target_is_the_min():
    rng = np.random.default_rng(4)
    psi, ph, pm = rng.uniform(0, 2 * np.pi, size=(3, 50, 2))
    target = eea_r_target(psi, ph, pm)
    h = np.abs(eea_residual(psi, target))
    expected = np.minimum(np.abs(wrap(psi - ph)), np.abs(wrap(psi - pm))) / np.pi
    np.testing.assert_allclose(h, expected)
    np.testing.assert_array_equal(eea_r_target(psi[:1], ph[:1], np.full((1, 2), np.nan)), ph[:1])


def test_forward_fill():
    x = np.array([[np.nan, 1.0], [2.0, np.nan], [np.nan, np.nan], [3.0, 4.0]])
    np.testing.assert_array_equal(forward_fill(x), [[2.0, 1.0], [2.0, 1.0], [2.0, 1.0], [3.0, 4.0]])


def printed_formula(p, rot):
    """Zanchettin's printed Ψ_human for an arm-frame hand position and orientation."""
    x, y, z = p
    th, ph, ps = Rotation.from_matrix(rot).as_euler(EULER)
    return (
        1.39
        - 0.88 * np.cos(th + 0.30)
        - 0.49 * np.cos(th + ph + 2.98)
        + 0.21 * np.arctan2(z, y)
        + 0.64 * np.sin(ps)
        + 0.50 * np.arctan2(x, y)
        + 0.22 * np.cos(ps + th + ph)
        - 0.47 * np.cos(ph + 0.60)
        + 0.40 * np.cos(ps + th)
    )


def test_published_predictor_reproduces_the_printed_formula():
    rng = np.random.default_rng(5)
    pred = SwivelPredictor.published()
    shoulder = np.array([[-0.2, 0.0, 1.4], [0.2, 0.0, 1.4]])
    d = np.diag(MIRROR)
    flip = np.diag([1.0, -1.0, 1.0])
    for _ in range(5):
        tcp = shoulder + rng.uniform([-0.3, 0.1, -0.5], [0.3, 0.6, 0.2], size=(2, 3))
        rot = Rotation.random(2, random_state=rng).as_matrix()
        got = pred.predict(shoulder, tcp, rot)
        right = printed_formula(tcp[1] - shoulder[1], rot[1])
        left = printed_formula((tcp[0] - shoulder[0]) * MIRROR, d @ rot[0] @ flip)
        np.testing.assert_allclose(got, np.mod([left, right], 2 * np.pi), atol=1e-12)


def test_predictor_mirror_symmetric(human):
    pred = SwivelPredictor.published()
    f = pred.features(human.shoulder, human.tcp_pos, human.tcp_rot)
    assert f.shape == (len(human.shoulder), 2, 12)
    # frame 0 of the demo is a left-right symmetric rest pose
    np.testing.assert_allclose(f[0, 0], f[0, 1], atol=1e-9)


def test_fit_on_demo(human):
    pred, rms = SwivelPredictor.fit(human.shoulder, human.elbow, human.wrist, human.tcp_pos, human.tcp_rot)
    assert pred.coef.shape == (12,)
    assert np.isfinite(rms) and rms < 0.2
    psi = swivel_angle(human.shoulder, human.elbow, human.wrist)
    err = wrap(pred.predict(human.shoulder, human.tcp_pos, human.tcp_rot) - psi)
    assert np.sqrt(np.mean(err**2)) == pytest.approx(rms)
