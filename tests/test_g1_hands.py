"""The G1's rubber hands have visual meshes only in the URDF: hlik fits a collision primitive to every
body with visual but no collision geometry (``hlik.robot.model_file.fit_collision_shapes``), so hands
through each other are a self-contact and the solvers keep them apart."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from conftest import G1, require_g1
from hlik.human.load import load_motion
from hlik.problem.scale import scale_subject
from hlik.retarget import retarget
from hlik.robot import model_file
from hlik.robot.collision import collision_pairs, near_pairs
from hlik.robot.model import COLLISION_GROUP, SIDES, joint_mapping, load_robot, self_contacts
from hlik.robot.model_file import FITTED
from hlik.robot.state import robot_state
from hlik.solvers import jv, qp

HANDS = ("left_rubber_hand", "right_rubber_hand")


@pytest.fixture(scope="module")
def g1():
    require_g1()
    return load_robot(str(G1))


@pytest.fixture(scope="module")
def bare_g1():
    """The G1 as compiled before: no primitives fitted to its visual-only bodies."""
    require_g1()
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(model_file, "fit_collision_shapes", lambda spec, model: [])
        return load_robot(str(G1))


def _hand_pairs(robot, q) -> list[tuple[str, str, float]]:
    return [c for c in self_contacts(robot, q) if c[0] in HANDS and c[1] in HANDS]


def test_visual_only_bodies_get_a_collision_primitive_covering_their_mesh(g1, bare_g1):
    """Both hands (and the pelvis and waist links) get one mass-less primitive, in the collision
    group, containing every vertex of the visual mesh; nothing else changes."""
    m = g1.model
    fitted = [g for g in range(m.ngeom) if m.geom(g).name.startswith(FITTED)]
    bodies = {m.body(m.geom_bodyid[g]).name for g in fitted}
    assert bodies == {*HANDS, "pelvis", "waist_yaw_link", "waist_roll_link"}
    assert m.ngeom == bare_g1.model.ngeom + len(fitted)
    np.testing.assert_array_equal(m.body_mass, bare_g1.model.body_mass)
    np.testing.assert_array_equal(m.body_inertia, bare_g1.model.body_inertia)
    for g in fitted:
        assert m.geom_group[g] == COLLISION_GROUP and m.geom_contype[g] and m.geom_conaffinity[g]
        assert m.geom_type[g] in (int(mujoco.mjtGeom.mjGEOM_BOX), int(mujoco.mjtGeom.mjGEOM_CAPSULE))
        body = m.geom_bodyid[g]
        (visual,) = [v for v in np.flatnonzero(m.geom_bodyid == body) if v != g]
        mesh = m.geom_dataid[visual]
        vert = m.mesh_vert[m.mesh_vertadr[mesh] : m.mesh_vertadr[mesh] + m.mesh_vertnum[mesh]]
        in_body = Rotation.from_quat(np.roll(m.geom_quat[visual], -1)).apply(vert) + m.geom_pos[visual]
        local = Rotation.from_quat(np.roll(m.geom_quat[g], -1)).inv().apply(in_body - m.geom_pos[g])
        size = m.geom_size[g]
        if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX:
            outside = np.max(np.abs(local) - size)
        else:
            axial = np.clip(local[:, 2], -size[1], size[1])
            outside = np.max(np.linalg.norm(local - np.c_[0 * axial, 0 * axial, axial], axis=1) - size[0])
        assert outside < 1e-9, f"{m.body(body).name}: a vertex {outside * 1e3:.2f} mm outside"
    hands = {(m.body(a).name, m.body(b).name) for a, b in collision_pairs(g1).bodies}
    assert HANDS in hands  # the hand pair is checked, and each hand against the body and other arm
    for hand in HANDS:
        for other in ("torso_link", "pelvis", "left_knee_link", "head_link"):
            assert tuple(sorted((hand, other))) in {tuple(sorted(p)) for p in hands}, (hand, other)


def _hands_together(robot, gap: float = 0.06) -> np.ndarray:
    """Damped least squares from home on the shoulder-yaw, elbow and wrist joints that brings the
    TCPs to ``gap`` (m) apart across the body, in front of it: the hands through each other."""
    m, data = robot.model, mujoco.MjData(robot.model)
    names = robot.joint_names
    free = np.array(
        [i for i, n in enumerate(names) if "shoulder_pitch" not in n and "shoulder_roll" not in n]
    )
    targets = robot_state(robot, robot.home).tcp[0].copy()
    targets[:, 0] = [-gap / 2, gap / 2]
    sites = [robot.site_id(s, "tcp") for s in SIDES]
    q = robot.home.copy()
    for _ in range(100):
        data.qpos[:] = q
        mujoco.mj_kinematics(m, data)
        mujoco.mj_comPos(m, data)
        jac, err = [], []
        for site, target in zip(sites, targets):
            j = np.zeros((3, m.nv))
            mujoco.mj_jacSite(m, data, j, None, site)
            jac.append(j[:, free])
            err.append(target - data.site_xpos[site])
        jac, err = np.vstack(jac), np.concatenate(err)
        q[free] += jac.T @ np.linalg.solve(jac @ jac.T + 1e-4 * np.eye(6), err)
        q = np.clip(q, robot.lower, robot.upper)
    return q


def test_hands_through_each_other_are_a_self_contact(g1, bare_g1):
    q = _hands_together(g1)
    pairs = _hand_pairs(g1, q)
    assert pairs and min(d for _, _, d in pairs) < -0.02  # 2 cm and more into each other
    # unseen before: no contact of a hand (MuJoCo 3.17 finds this pose's right elbow grazing the
    # torso by 3 mm, an earlier release did not; the arms' geoms are the G1's, not this test's)
    assert not _hand_pairs(bare_g1, q)
    assert not [c for c in self_contacts(bare_g1, q) if c[0] in HANDS or c[1] in HANDS]
    assert not self_contacts(g1, g1.home)


@pytest.fixture(scope="module")
def close_take(takes):
    """The Close take, 3.0-7.0 s at 50 Hz: the joint-mapped G1's hands pass 4 cm into each other."""
    (path,) = [p for p in takes if p.name.startswith("Close_")]
    return load_motion(path, rate=50.0).crop(3.0, 7.0)


def test_the_qp_keeps_the_hands_apart_where_jm_puts_them_through_each_other(g1, close_take):
    motion = scale_subject(close_take, g1)
    jm = joint_mapping(g1, motion)
    assert sum(bool(_hand_pairs(g1, q)) for q in jm) > 20
    traj = retarget(motion, g1, qp.qp_solver(qp.QPSettings()))
    touching = [k for k, q in enumerate(traj.q) if _hand_pairs(g1, q)]
    assert not touching, f"hands touch in {len(touching)} of {len(traj.q)} frames"
    other = [k for k, q in enumerate(traj.q) if any(set(c[:2]) & set(HANDS) for c in self_contacts(g1, q))]
    assert not other, f"a hand touches the body or the other arm in {len(other)} frames"


@pytest.mark.parametrize("solver", [qp.qp_solver(), jv.jv_solver()], ids=["qp", "jv"])
def test_the_arms_do_not_coast_into_the_torso(g1, cut_take, solver):
    """On the Cut take the G1's upper arms come within the margin of its torso (its collision mesh's
    convex hull) for seconds at a time, and the collision rows, the torque and the acceleration
    rows cannot all be met. The fallback used to relax every row to "no worse than the frame's
    start", the constant-speed prediction: the arm coasted into the torso at its speed (5.7 cm deep
    after 30 frames, in 158 of 500 frames). Missing the rows as little as the limits allow keeps
    every body apart."""
    motion = scale_subject(load_motion(cut_take, rate=100.0).crop(1.0, 6.0), g1)
    traj = retarget(motion, g1, solver)
    deepest = {k: self_contacts(g1, q)[0] for k, q in enumerate(traj.q) if self_contacts(g1, q)}
    assert not deepest, f"{len(deepest)} frames in self-contact, e.g. {next(iter(deepest.items()))}"


def test_parts_of_one_joint_are_not_collision_pairs(g1):
    """The G1's shoulder pitch links sit 8 mm from the convex hull of its torso mesh, and its wrist
    links from each other, whatever the joints do: excluded (closer than 1 cm at home and in every
    sampled configuration). At home, every pair left inside the 1 cm margin is one the joints can
    move apart, so no solver pushes at a distance it cannot change; the upper arm against the torso
    stays a pair."""
    m = g1.model
    pairs = collision_pairs(g1)
    names = {frozenset((m.body(int(a)).name, m.body(int(b)).name)) for a, b in pairs.bodies}
    for side in ("left", "right"):
        assert {"torso_link", f"{side}_shoulder_pitch_link"} not in names
        assert {f"{side}_wrist_roll_link", f"{side}_wrist_yaw_link"} not in names
        assert {"torso_link", f"{side}_shoulder_yaw_link"} in names
    data = mujoco.MjData(m)
    data.qpos[:] = g1.home
    mujoco.mj_kinematics(m, data)
    mujoco.mj_comPos(m, data)
    _, dist, grad = near_pairs(g1, data, pairs, 0.01)
    assert len(dist) and np.all(np.linalg.norm(grad, axis=1) > 0.01)
