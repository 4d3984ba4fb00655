"""Collision geometry of the robot models (robots/mjcf/*.xml, default class ``collision``).

Collision geoms are group 3 primitives with contype = conaffinity = 1 and no mass; the visual geoms
(group 1) never collide. :func:`hlik.robot.self_contacts` must report nothing at rest (home pose, JM
pose of the demo's first frame), never a body against its parent or two parts of one hand, and
must report an arm pushed through the torso or into the other arm.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from conftest import ROBOTS
from hlik.human.demo import demo_motion
from hlik.robot.model import (
    COLLISION_GROUP,
    SIDES,
    VISUAL_GROUP,
    joint_mapping,
    load_robot,
    self_contacts,
)

PRIMITIVES = {
    int(mujoco.mjtGeom.mjGEOM_SPHERE),
    int(mujoco.mjtGeom.mjGEOM_CAPSULE),
    int(mujoco.mjtGeom.mjGEOM_BOX),
    int(mujoco.mjtGeom.mjGEOM_CYLINDER),
}


@pytest.fixture(scope="module", params=ROBOTS)
def robot(request):
    return load_robot(request.param)


def _collision(model: mujoco.MjModel) -> np.ndarray:
    return model.geom_group == COLLISION_GROUP


def _subtree(model: mujoco.MjModel, root: int) -> set[int]:
    """Body ``root`` and all its descendants."""
    out = {root}
    for b in range(root + 1, model.nbody):  # MuJoCo orders bodies parents first
        if model.body_parentid[b] in out:
            out.add(b)
    return out


def _arm_bodies(robot, side: str) -> set[int]:
    """Bodies moved by the arm's first joint (the whole arm, hand included)."""
    m = robot.model
    return _subtree(m, int(m.jnt_bodyid[m.joint(robot.arm_joints[side][0]).id]))


def _hand_bodies(robot, side: str) -> set[int]:
    """Parts of one hand: the bodies between the forearm (body of the wrist site) and the TCP body,
    and the TCP body's subtree."""
    m = robot.model
    forearm = int(m.site_bodyid[robot.site_id(side, "wrist")])
    tcp = int(m.site_bodyid[robot.site_id(side, "tcp")])
    hand = _subtree(m, tcp)
    b = tcp
    while b not in (forearm, 0):
        hand.add(b)
        b = int(m.body_parentid[b])
    return hand


def _torso_bodies(robot) -> set[int]:
    """Bodies with geoms that belong to neither arm: platform, column/torso, head."""
    m = robot.model
    arms = _arm_bodies(robot, "left") | _arm_bodies(robot, "right")
    return {int(m.geom_bodyid[g]) for g in range(m.ngeom)} - arms


def _ids(model: mujoco.MjModel, contacts) -> list[tuple[int, int, float]]:
    return [(model.body(a).id, model.body(b).id, d) for a, b, d in contacts]


# ------------------------------------------------------------------------------------------- geoms
def test_collision_geoms_exist_and_visual_geoms_do_not_collide(robot):
    m = robot.model
    col = _collision(m)
    assert col.sum() >= 10, f"{robot.name}: only {col.sum()} collision geoms"
    for g in range(m.ngeom):
        name = m.geom(g).name
        if col[g]:
            assert name.startswith("col_"), f"{robot.name}: collision geom {g} named {name!r}"
            assert int(m.geom_type[g]) in PRIMITIVES, name
            assert m.geom_contype[g] != 0 and m.geom_conaffinity[g] != 0, name
            assert m.geom_margin[g] == 0, name
        else:
            assert m.geom_group[g] == VISUAL_GROUP, f"{robot.name}: geom {name!r} in group {m.geom_group[g]}"
            assert m.geom_contype[g] == 0 and m.geom_conaffinity[g] == 0, name
    names = [m.geom(g).name for g in np.flatnonzero(col)]
    assert len(set(names)) == len(names)


def test_every_body_with_a_visual_geom_has_a_collision_geom(robot):
    m = robot.model
    col = _collision(m)
    visual_bodies = {int(b) for b in m.geom_bodyid[~col]}
    collision_bodies = {int(b) for b in m.geom_bodyid[col]}
    missing = [m.body(b).name for b in sorted(visual_bodies - collision_bodies)]
    assert not missing, f"{robot.name}: bodies without collision geoms: {missing}"


def test_collision_geoms_are_massless(robot):
    """Body masses and inertias equal those of the same model with every collision geom deleted."""
    spec = mujoco.MjSpec.from_file(str(robot.model_file))
    deleted = 0
    for geom in list(spec.geoms):
        if geom.group == COLLISION_GROUP:
            spec.delete(geom)
            deleted += 1
    assert deleted == _collision(robot.model).sum()
    bare = spec.compile()
    assert bare.nbody == robot.model.nbody and bare.ngeom == robot.model.ngeom - deleted
    m = robot.model
    np.testing.assert_allclose(m.body_mass, bare.body_mass, rtol=0, atol=1e-12)
    np.testing.assert_allclose(m.body_inertia, bare.body_inertia, rtol=0, atol=1e-12)
    np.testing.assert_allclose(m.body_ipos, bare.body_ipos, rtol=0, atol=1e-12)
    assert m.body_mass.sum() > 1.0  # the visual geoms still carry the robot's mass


def _inside(model: mujoco.MjModel, data: mujoco.MjData, g: int, p: np.ndarray, tol: float) -> bool:
    """Point ``p`` (world) inside collision geom ``g`` (primitives only), up to ``tol``."""
    x = data.geom_xmat[g].reshape(3, 3).T @ (p - data.geom_xpos[g])
    s = model.geom_size[g]
    t = int(model.geom_type[g])
    if t == mujoco.mjtGeom.mjGEOM_SPHERE:
        return np.linalg.norm(x) <= s[0] + tol
    if t == mujoco.mjtGeom.mjGEOM_CAPSULE:
        return np.hypot(np.linalg.norm(x[:2]), max(abs(x[2]) - s[1], 0.0)) <= s[0] + tol
    if t == mujoco.mjtGeom.mjGEOM_CYLINDER:
        return np.linalg.norm(x[:2]) <= s[0] + tol and abs(x[2]) <= s[1] + tol
    return bool(np.all(np.abs(x) <= s + tol))  # box


def _surface_points(model: mujoco.MjModel, data: mujoco.MjData, g: int) -> np.ndarray:
    """Centre and extreme points (along the geom's axes; box corners) of visual geom ``g``, world."""
    s = model.geom_size[g]
    t = int(model.geom_type[g])
    if t == mujoco.mjtGeom.mjGEOM_SPHERE:
        local = np.vstack([np.zeros(3), np.eye(3) * s[0], -np.eye(3) * s[0]])
    elif t == mujoco.mjtGeom.mjGEOM_BOX:
        local = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)]) * s[:3]
        local = np.vstack([np.zeros(3), local])
    else:  # capsule, cylinder: rim points at both ends; a capsule adds its two poles
        r, h = s[0], s[1]
        rim = [[a * r, b * r, z] for z in (-h, h) for a, b in ((1, 0), (-1, 0), (0, 1), (0, -1))]
        poles = [[0, 0, h + r], [0, 0, -h - r]] if t == mujoco.mjtGeom.mjGEOM_CAPSULE else []
        local = np.array([[0, 0, 0], *rim, *poles], dtype=float)
    return data.geom_xpos[g] + local @ data.geom_xmat[g].reshape(3, 3).T


def test_collision_geoms_cover_the_visual_geoms(robot):
    """At home, the centre and extreme points of every visual geom lie in some collision geom."""
    m = robot.model
    d = mujoco.MjData(m)
    d.qpos[:] = robot.home
    mujoco.mj_kinematics(m, d)
    col = np.flatnonzero(_collision(m))
    uncovered = []
    for g in np.flatnonzero(~_collision(m)):
        for p in _surface_points(m, d, g):
            if not any(_inside(m, d, c, p, tol=2e-3) for c in col):
                uncovered.append(
                    (m.geom(g).name or f"geom {g} of {m.body(m.geom_bodyid[g]).name}", p.round(3))
                )
    assert not uncovered, f"{robot.name}: visual points outside every collision geom: {uncovered[:5]}"


# ------------------------------------------------------------------------------------- rest poses
def test_no_self_contact_at_home(robot):
    assert self_contacts(robot, robot.home) == []


def test_no_self_contact_at_demo_jm_first_frame(robot):
    q = joint_mapping(robot, demo_motion())[0]
    assert self_contacts(robot, q) == []


# -------------------------------------------------------------------------------- filtered pairs
def test_adjacent_links_and_hand_parts_never_count():
    """300 random configurations per robot: no contact between a body and its parent, or between two
    parts of one hand; every distance finite and <= 0."""
    rng = np.random.default_rng(20240611)
    for name in ROBOTS:
        robot = load_robot(name)
        m = robot.model
        d = mujoco.MjData(m)
        lo = np.where(np.isfinite(robot.lower), robot.lower, -np.pi)
        hi = np.where(np.isfinite(robot.upper), robot.upper, np.pi)
        hands = [_hand_bodies(robot, s) for s in SIDES]
        assert all(len(h) >= 1 for h in hands)
        for _ in range(300):
            q = rng.uniform(lo, hi)
            for b1, b2, dist in _ids(m, self_contacts(robot, q, d)):
                pair = f"{name}: {m.body(b1).name} / {m.body(b2).name} at q={np.round(q, 3).tolist()}"
                assert np.isfinite(dist) and dist <= 0, pair
                assert b1 != b2, pair
                assert m.body_parentid[b1] != b2 and m.body_parentid[b2] != b1, pair
                assert not any(b1 in h and b2 in h for h in hands), pair


# ------------------------------------------------------------------------------- contacts found
def _reach(robot, side: str, site: str, target: np.ndarray, seeds: int = 6, start=None) -> np.ndarray:
    """Configuration that puts ``{side}_{site}`` closest to ``target``, moving only that arm (the other
    joints as in ``start``, default home): damped least squares within the limits, from ``start`` and
    a few random arm starts. The caller checks where the site ended up (a target may be out of reach)."""
    m = robot.model
    d = mujoco.MjData(m)
    idx = robot.index(robot.arm_joints[side])
    dofs = np.array([m.jnt_dofadr[m.joint(j).id] for j in robot.arm_joints[side]])
    sid = robot.site_id(side, site)
    lo = np.where(np.isfinite(robot.lower), robot.lower, -np.pi)[idx]
    hi = np.where(np.isfinite(robot.upper), robot.upper, np.pi)[idx]
    rng = np.random.default_rng(7)
    start = robot.home if start is None else start
    best, best_err = start.copy(), np.inf
    jac = np.zeros((3, m.nv))
    for k in range(seeds):
        q = start.copy()
        if k:
            q[idx] = rng.uniform(lo, hi)
        for _ in range(200):
            d.qpos[:] = q
            mujoco.mj_kinematics(m, d)
            mujoco.mj_comPos(m, d)
            err = target - d.site_xpos[sid]
            if np.linalg.norm(err) < 1e-3:
                break
            mujoco.mj_jacSite(m, d, jac, None, sid)
            J = jac[:, dofs]
            step = J.T @ np.linalg.solve(J @ J.T + 1e-3 * np.eye(3), err)
            q[idx] = np.clip(q[idx] + np.clip(step, -0.3, 0.3), robot.lower[idx], robot.upper[idx])
        d.qpos[:] = q
        mujoco.mj_kinematics(m, d)
        e = np.linalg.norm(target - d.site_xpos[sid])
        if e < best_err:
            best, best_err = q.copy(), e
    return best


def _site_pos(robot, q: np.ndarray, side: str, site: str) -> np.ndarray:
    d = mujoco.MjData(robot.model)
    d.qpos[:] = q
    mujoco.mj_kinematics(robot.model, d)
    return d.site_xpos[robot.site_id(side, site)].copy()


def _torso_point(robot) -> tuple[np.ndarray, int]:
    """A point inside a torso collision geom, and that geom: on the midline (x = 0), 0.2 m below the
    shoulders, at the depth (y) of the geom's centre."""
    m = robot.model
    d = mujoco.MjData(m)
    d.qpos[:] = robot.home
    mujoco.mj_kinematics(m, d)
    z = np.mean([d.site_xpos[robot.site_id(s, "shoulder")][2] for s in SIDES]) - 0.2
    torso = _torso_bodies(robot)
    for g in np.flatnonzero(_collision(m)):
        point = np.array([0.0, d.geom_xpos[g][1], z])
        if m.geom_bodyid[g] in torso and _inside(m, d, g, point, tol=-0.03):  # >= 3 cm deep
            return point, int(g)
    raise AssertionError(f"{robot.name}: no torso collision geom 0.2 m below the shoulders")


@pytest.mark.parametrize("site", ["wrist", "tcp"])
def test_arm_through_torso_is_a_contact(robot, site):
    """Right wrist (forearm end) or right TCP (hand) pushed into the torso: a torso / right-arm contact."""
    target, geom = _torso_point(robot)
    q = _reach(robot, "right", site, target)
    m = robot.model
    d = mujoco.MjData(m)
    d.qpos[:] = q
    mujoco.mj_kinematics(m, d)
    reached = d.site_xpos[robot.site_id("right", site)]
    assert _inside(m, d, geom, reached, tol=-0.01), (
        f"{robot.name}: right {site} at {reached}, not in the torso"
    )
    contacts = self_contacts(robot, q, d)
    assert all(np.isfinite(c[2]) for c in contacts)
    torso, arm = _torso_bodies(robot), _arm_bodies(robot, "right")
    hits = [
        (b1, b2, dist)
        for b1, b2, dist in _ids(robot.model, contacts)
        if dist < 0 and ((b1 in torso and b2 in arm) or (b2 in torso and b1 in arm))
    ]
    assert hits, f"{robot.name}: right {site} in the torso, contacts {contacts}"


def test_hand_on_other_wrist_is_a_contact(robot):
    """Right wrist brought to the midline in front of the chest, left TCP put on it: an arm-arm contact."""
    home = robot.home
    shoulder = np.mean([_site_pos(robot, home, s, "shoulder") for s in SIDES], axis=0)
    front = shoulder + np.array([0.0, 0.35, -0.2])
    q = _reach(robot, "right", "wrist", front)
    wrist = _site_pos(robot, q, "right", "wrist")
    assert np.linalg.norm(wrist - front) < 0.05, f"{robot.name}: right wrist at {wrist}, target {front}"
    q = _reach(robot, "left", "tcp", wrist, start=q)
    reached = _site_pos(robot, q, "left", "tcp")
    assert np.linalg.norm(reached - wrist) < 0.02, f"{robot.name}: left TCP at {reached}, target {wrist}"
    contacts = self_contacts(robot, q)
    assert all(np.isfinite(c[2]) for c in contacts)
    left, right = _arm_bodies(robot, "left"), _arm_bodies(robot, "right")
    hits = [
        (b1, b2, dist)
        for b1, b2, dist in _ids(robot.model, contacts)
        if dist < 0 and ((b1 in left and b2 in right) or (b2 in left and b1 in right))
    ]
    assert hits, f"{robot.name}: left hand on the right wrist, contacts {contacts}"
