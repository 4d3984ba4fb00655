"""Posture measures (hlik.posture) on constructed poses: a hunched trunk, an elbow behind the back, a
mirrored pair, a body moved and turned on the floor; and on the robots' own kinematics."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from hlik import load_motion, load_robot, retarget
from hlik.posture import BEHIND, body_posture, path_ratio, posture, robot_posture

# a person standing at the origin facing +y (x right, z up): shoulders, elbows, wrists, hands
SHOULDER = np.array([[-0.2, 0.0, 1.4], [0.2, 0.0, 1.4]])
ELBOW = np.array([[-0.22, 0.05, 1.12], [0.22, 0.02, 1.12]])
WRIST = np.array([[-0.2, 0.3, 1.0], [0.18, 0.28, 1.02]])
TCP = WRIST + np.array([0.0, 0.08, 0.0])
PELVIS = np.array([0.0, 0.0, 0.95])


def _measure(shoulder, elbow, wrist, tcp, pelvis):
    one = lambda a: np.asarray(a, dtype=float)[None]  # noqa: E731
    trunk = one(shoulder.mean(axis=0) - pelvis)
    return body_posture(one(shoulder), one(elbow), one(wrist), one(tcp), trunk)


def test_an_upright_person_has_no_lean_and_the_offsets_of_the_construction():
    p = _measure(SHOULDER, ELBOW, WRIST, TCP, PELVIS)
    assert abs(p.lean[0]) < 1e-12
    np.testing.assert_allclose(p.elbow_front[0], ELBOW[:, 1])
    np.testing.assert_allclose(p.hand_front[0], TCP[:, 1])
    length = np.linalg.norm(ELBOW - SHOULDER, axis=1) + np.linalg.norm(WRIST - ELBOW, axis=1)
    np.testing.assert_allclose(p.arm_length, length)


def test_a_long_hand_on_the_subjects_tcp_is_ahead_but_its_wrist_is_where_the_arm_poses_it():
    """The same arm posture with a hand twice the subject's length, pointing forward: the TCP front
    grows by the extra length and the wrist front stays; the wrist ratio is 1, the TCP ratio is not."""
    subject = _measure(SHOULDER, ELBOW, WRIST, TCP, PELVIS)
    robot = _measure(SHOULDER, ELBOW, WRIST, WRIST + 2 * (TCP - WRIST), PELVIS)
    np.testing.assert_allclose(robot.wrist_front[0], WRIST[:, 1])
    np.testing.assert_allclose(robot.hand_front[0] - subject.hand_front[0], 0.08)
    np.testing.assert_allclose(robot.wrist_front_share / subject.wrist_front_share, 1.0)
    assert np.all(robot.hand_front_share / subject.hand_front_share > 1.2)


@pytest.mark.parametrize("angle", [0.3, -0.2, 0.6])
def test_a_hunched_trunk_leans_by_its_pitch(angle):
    """The upper body pitched forward about the pelvis (about the x axis, right): lean = the pitch,
    forward positive."""
    forward = Rotation.from_rotvec([-angle, 0.0, 0.0])  # about -x: z tips toward +y, forward
    move = lambda x: forward.apply(x - PELVIS) + PELVIS  # noqa: E731
    p = _measure(move(SHOULDER), move(ELBOW), move(WRIST), move(TCP), PELVIS)
    assert p.lean[0] == pytest.approx(angle, abs=1e-9)


def test_an_elbow_behind_the_back_is_told():
    elbow = ELBOW.copy()
    elbow[1, 1] = -0.12  # the right elbow 12 cm behind the shoulders
    p = _measure(SHOULDER, elbow, WRIST, TCP, PELVIS)
    assert p.elbow_front[0, 1] == pytest.approx(-0.12)
    assert p.elbow_behind[0].tolist() == [False, True] and -0.12 < -BEHIND


def test_a_mirrored_pair_swaps_the_arms():
    """Mirrored through the sagittal plane (x -> -x, left <-> right) every per-arm measure swaps arms
    and the swivel angle (defined mirrored for the left arm) stays."""
    mirror = lambda x: (x * [-1.0, 1.0, 1.0])[::-1]  # noqa: E731
    p = _measure(SHOULDER, ELBOW, WRIST, TCP, PELVIS)
    m = _measure(mirror(SHOULDER), mirror(ELBOW), mirror(WRIST), mirror(TCP), PELVIS)
    for a, b in ((p.elbow_front, m.elbow_front), (p.hand_front, m.hand_front), (p.swivel, m.swivel)):
        np.testing.assert_allclose(a[0], b[0][::-1], atol=1e-12)
    assert m.lean[0] == pytest.approx(p.lean[0], abs=1e-12)


@settings(max_examples=50, deadline=None)
@given(
    yaw=st.floats(-np.pi, np.pi),
    shift=st.tuples(st.floats(-3, 3), st.floats(-3, 3)),
    pitch=st.floats(-0.5, 0.5),
)
def test_measures_do_not_depend_on_where_the_body_stands_or_faces(yaw, shift, pitch):
    lean = Rotation.from_rotvec([-pitch, 0.0, 0.0])
    base = [lean.apply(x - PELVIS) + PELVIS for x in (SHOULDER, ELBOW, WRIST, TCP)]
    turn = Rotation.from_rotvec([0.0, 0.0, yaw])
    offset = np.array([shift[0], shift[1], 0.0])
    moved = [turn.apply(x) + offset for x in base]
    a = _measure(*base, PELVIS)
    b = _measure(*moved, turn.apply(PELVIS) + offset)
    for x, y in ((a.lean, b.lean), (a.elbow_front, b.elbow_front), (a.hand_front, b.hand_front)):
        np.testing.assert_allclose(x, y, atol=1e-9)
    np.testing.assert_allclose(np.cos(a.swivel - b.swivel), 1.0, atol=1e-9)


def test_armar3_leans_with_its_hip_and_the_fixed_torsos_never():
    r = load_robot("armar3")
    pitch = r.joint_names.index("HipPitch")
    q = np.tile(r.home, (3, 1))
    q[:, pitch] += [0.0, 0.2, 0.4]
    lean = robot_posture(r, q).lean
    np.testing.assert_allclose(np.abs(lean - lean[0]), [0.0, 0.2, 0.4], atol=1e-9)
    for name in ("armar6", "dual_panda"):
        r = load_robot(name)
        rng = np.random.default_rng(0)
        q = rng.uniform(np.maximum(r.lower, -3), np.minimum(r.upper, 3), (20, r.dof))
        assert np.allclose(robot_posture(r, q).lean, 0.0, atol=1e-12), name


def test_the_joint_mapping_moves_as_far_as_the_person(takes):
    """JM is the mapped human pose clipped to the joint limits: its path is the person's where no
    joint is clipped, a little less where one is."""
    r = load_robot("armar6")
    traj = retarget(load_motion(takes[0], rate=100.0).crop(1.0, 3.0), r)
    assert 0.8 < path_ratio(traj, r) <= 1.0 + 1e-12
    measured = posture(traj, r).to_json()
    assert measured["path_ratio"] == pytest.approx(path_ratio(traj, r))
    assert len(measured["elbow_front_share"]) == 2


@settings(max_examples=50, deadline=None)
@given(st.lists(st.floats(-2, 2), min_size=6, max_size=6))
def test_the_shoulder_axes_are_horizontal_orthonormal_and_right_handed(values):
    from hlik.human.kinematics import shoulder_axes

    left, right = np.array(values[:3]), np.array(values[3:])
    if np.hypot(*(right - left)[:2]) < 1e-3:
        return
    across, front = shoulder_axes(left, right)
    assert across[2] == 0.0 and front[2] == 0.0
    np.testing.assert_allclose(
        [np.linalg.norm(across), np.linalg.norm(front), across @ front], [1, 1, 0], atol=1e-12
    )
    np.testing.assert_allclose(np.cross(across, front), [0.0, 0.0, 1.0], atol=1e-12)


@pytest.mark.parametrize("name", ["armar3", "armar6", "dual_panda"])
def test_elbows_ahead_has_the_jacobian_of_its_residual_and_acts_only_behind(name):
    """ElbowsAhead (issue 28): its Jacobian is the central difference of its residual (ARMAR-III's
    hip moves the shoulders and turns the plane), and it is zero, with a zero Jacobian, wherever
    both elbows are in front of the allowance; its residual is how far behind an elbow is."""
    from hlik.criteria.elbows import ElbowsAhead
    from hlik.robot.state import robot_state

    robot = load_robot(name)
    rng = np.random.default_rng(7)
    everywhere = ElbowsAhead(allowance=-1.0)  # active in any pose: the derivative is checked
    for _ in range(3):
        q = np.clip(robot.home + rng.normal(0.0, 0.3, robot.dof), robot.lower, robot.upper)
        state = robot_state(robot, q[None], jacobians=True)
        jac = everywhere.jacobian(state, None)[0]
        fd = np.empty_like(jac)
        for k in range(robot.dof):
            dq = np.zeros(robot.dof)
            dq[k] = 1e-6
            up, down = (everywhere.residual(robot_state(robot, (q + s * dq)[None]), None)[0] for s in (1, -1))
            fd[:, k] = (up - down) / 2e-6
        np.testing.assert_allclose(jac, fd, atol=1e-7)
    home = robot_state(robot, robot.home[None], jacobians=True)
    term = ElbowsAhead()
    ahead = robot_posture(robot, robot.home[None]).elbow_front  # share of an arm's length
    e = term.residual(home, None)[0]
    assert np.all(e >= 0) and np.all((e > 0) == (everywhere.residual(home, None)[0] > 1.02))
    assert np.all(e[ahead[0] > 0] == 0) and np.all(term.jacobian(home, None)[0][e == 0] == 0)
