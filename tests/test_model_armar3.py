"""ARMAR-III model (robots/mjcf/armar3.xml, robots/armar3.toml) against kinematics.md §2 and §9.

Checks the zero-pose geometry table of §2.2, an independent forward kinematics of the Simox
standard-DH chain (T = Rz(theta) Tz(d) Tx(a) Rx(alpha)) at random joint angles, the joint limits,
the sites and TCP frame convention of robots/README.md, and the toml description.
"""

import math
from pathlib import Path

import mujoco
import numpy as np
import pytest
import tomllib

ROOT = Path(__file__).resolve().parents[1]
MJCF = ROOT / "robots/mjcf/armar3.xml"
TOML = ROOT / "robots/armar3.toml"

ARM = ["Shoulder1", "Shoulder2", "Upperarm", "Elbow", "Underarm", "Wrist1", "Wrist2"]
SIDES = {"R": "right", "L": "left"}

HIP = np.array([0.0, 0.158, 0.890])
COA = HIP + np.array([0.0, -0.035, 0.485])  # "Center of Arms" in the model (world) frame

C15, S15 = math.cos(math.radians(15)), math.sin(math.radians(15))

# §2.2 "Zero-pose geometry", right arm, Center-of-Arms frame, mm (axes with exact cos/sin 15 deg).
TABLE_R = {
    "Shoulder1": ((232.0, 0.0, 0.0), (-1, 0, 0)),
    "Shoulder2": ((232.0, 0.0, 0.0), (0, -1, 0)),
    "Upperarm": ((232.0, 0.0, 0.0), (-S15, 0, C15)),
    "Elbow": ((312.2, 20.0, -299.4), (C15, 0, S15)),
    "Underarm": ((319.5, 20.0, -297.5), (0, -1, 0)),
    "Wrist1": ((319.5, 260.0, -297.5), (S15, 0, -C15)),
    "Wrist2": ((319.5, 260.0, -297.5), (-C15, 0, -S15)),
}
TCP_R_MM = (319.5, 390.0, -297.5)
# Left arm: origins are the x-mirror of the right's; axes from the Simox left-arm chain (§2.2 with
# Shoulder 2 theta = 75 deg and Underarm d = -7.5 mm), which keeps the Simox left limits meaningful.
AXES_L = {
    "Shoulder1": (-1, 0, 0),
    "Shoulder2": (0, -1, 0),
    "Upperarm": (S15, 0, C15),
    "Elbow": (C15, 0, -S15),
    "Underarm": (0, -1, 0),
    "Wrist1": (-S15, 0, -C15),
    "Wrist2": (-C15, 0, S15),
}

# §2.2 limits, degrees
LIMITS = {
    "R": {
        "Shoulder1": (-106.94, 80),
        "Shoulder2": (-13.85, 94.62),
        "Upperarm": (-108.11, 73.94),
        "Elbow": (-114.58, 55),
        "Underarm": (-69.65, 108.25),
        "Wrist1": (-29.18, 29.88),
        "Wrist2": (-30.9, 50.87),
    },
    "L": {
        "Shoulder1": (-106.91, 80),
        "Shoulder2": (-94.62, 13.85),
        "Upperarm": (-69.65, 108.25),
        "Elbow": (-122.96, 55),
        "Underarm": (-108.25, 69.65),
        "Wrist1": (-29.36, 24.11),
        "Wrist2": (-38.4, 44.32),
    },
}

POS_TOL = 1e-3  # m
AXIS_TOL = 1e-3


# ---------------------------------------------------------------- independent Simox DH kinematics
def _rz(t):
    c, s = math.cos(t), math.sin(t)
    m = np.eye(4)
    m[:2, :2] = [[c, -s], [s, c]]
    return m


def _rx(t):
    c, s = math.cos(t), math.sin(t)
    m = np.eye(4)
    m[1:3, 1:3] = [[c, -s], [s, c]]
    return m


def _tr(x, y, z):
    m = np.eye(4)
    m[:3, 3] = [x, y, z]
    return m


def _dh(a, d, theta, alpha):
    """Simox standard DH (mm, deg) -> homogeneous transform in metres."""
    return _rz(math.radians(theta)) @ _tr(0, 0, d / 1000) @ _tr(a / 1000, 0, 0) @ _rx(math.radians(alpha))


def _arm_dh(side):
    """Per-joint DH transforms of §2.2 (before each joint), then EndArm."""
    sh2 = 105 if side == "R" else 75
    ua_d = 7.5 if side == "R" else -7.5
    return [
        [(0, 0, -90, 90), (0, 0, 90, 0)],  # Arm Base, Shoulder 1
        [(0, 0, 0, 90), (0, 0, sh2, 0)],  # Shoulder 2
        [(0, 0, 0, 90), (0, 0, -90, 0)],  # Upperarm
        [(20, -310, 0, 90), (0, 0, 90, 0)],  # Elbow
        [(0, ua_d, 0, -90), (0, 0, 90, 0)],  # Underarm
        [(0, -240, 0, -90), (0, 0, -90, 0)],  # Wrist 1
        [(0, 0, 0, -90), (0, 0, -90, 0)],  # Wrist 2
    ]


def simox_fk(side, q_arm, hip_pitch=0.0, hip_yaw=0.0):
    """Joint frames (4x4, before rotation) of the 7 arm joints and the TCP frame, in the platform frame."""
    sign = 1 if side == "R" else -1
    t = _tr(*HIP) @ _rx(hip_pitch) @ _rz(hip_yaw) @ _tr(0, -0.035, 0.485) @ _tr(sign * 0.232, 0, 0)
    frames = []
    for dhs, q in zip(_arm_dh(side), q_arm):
        for p in dhs:
            t = t @ _dh(*p)
        frames.append(t.copy())
        t = t @ _rz(q)
    tcp = t @ _dh(0, 0, 0, 90) @ _tr(0, 0, 0.130)  # EndArm, TCP
    return frames, tcp


# ---------------------------------------------------------------- fixtures / helpers
@pytest.fixture(scope="module")
def model():
    return mujoco.MjModel.from_xml_path(str(MJCF))


@pytest.fixture(scope="module")
def desc():
    with open(TOML, "rb") as f:
        return tomllib.load(f)


def _fk(model, q=None):
    data = mujoco.MjData(model)
    if q:
        for name, val in q.items():
            data.qpos[model.joint(name).qposadr[0]] = val
    mujoco.mj_kinematics(model, data)
    return data


def _site(model, data, name):
    i = model.site(name).id
    return data.site_xpos[i].copy(), data.site_xmat[i].reshape(3, 3).copy()


def _joint(model, data, name):
    j = model.joint(name).id
    return data.xanchor[j].copy(), data.xaxis[j].copy()


def _is_descendant(model, body, ancestor):
    while True:
        if body == ancestor:
            return True
        if body == 0:
            return False
        body = model.body_parentid[body]


# ---------------------------------------------------------------- structure
def test_loads_and_joint_set(model):
    names = {model.joint(i).name for i in range(model.njnt)}
    expected = {"HipPitch", "HipYaw"} | {f"{j}_{s}" for j in ARM for s in SIDES}
    assert names == expected
    assert model.nq == model.nv == 16
    assert all(model.jnt_type[i] == mujoco.mjtJoint.mjJNT_HINGE for i in range(model.njnt))


def test_base_on_floor(model):
    base = model.body("base")
    assert base.parentid[0] == 0  # child of the world, fixed (no joint)
    assert base.jntnum[0] == 0
    np.testing.assert_allclose(model.body_pos[base.id], 0.0)
    np.testing.assert_allclose(model.body_quat[base.id], [1, 0, 0, 0])


def test_geoms_visual_primitives(model):
    prim = {
        int(mujoco.mjtGeom.mjGEOM_SPHERE),
        int(mujoco.mjtGeom.mjGEOM_CAPSULE),
        int(mujoco.mjtGeom.mjGEOM_BOX),
        int(mujoco.mjtGeom.mjGEOM_CYLINDER),
    }
    assert model.ngeom > 0
    for g in range(model.ngeom):
        assert int(model.geom_type[g]) in prim
        if model.geom_group[g] == 1:  # visual; collision geoms (group 3): tests/test_collision.py
            assert model.geom_contype[g] == 0 and model.geom_conaffinity[g] == 0
        else:
            assert model.geom_group[g] == 3


# ---------------------------------------------------------------- hip, shoulder height
def test_hip_joints(model):
    data = _fk(model)
    for name, axis in (("HipPitch", (1, 0, 0)), ("HipYaw", (0, 0, 1))):
        anchor, ax = _joint(model, data, name)
        np.testing.assert_allclose(anchor, HIP, atol=1e-9)
        np.testing.assert_allclose(ax, axis, atol=1e-9)
        np.testing.assert_allclose(model.jnt_range[model.joint(name).id], np.radians([-45, 45]), atol=1e-6)
    # pitch is proximal to yaw
    assert _is_descendant(model, model.joint("HipYaw").bodyid[0], model.joint("HipPitch").bodyid[0])


def test_shoulder_height(model):
    data = _fk(model)
    for side in SIDES.values():
        pos, _ = _site(model, data, f"{side}_shoulder")
        assert pos[2] == pytest.approx(0.890 + 0.485, abs=1e-9)
        assert pos[1] == pytest.approx(0.158 - 0.035, abs=1e-9)
        assert pos[0] == pytest.approx(0.232 if side == "right" else -0.232, abs=1e-9)


# ---------------------------------------------------------------- zero-pose table §2.2
@pytest.mark.parametrize("side", ["R", "L"])
def test_zero_pose_table(model, side):
    data = _fk(model)
    mirror = np.array([1.0, 1, 1]) if side == "R" else np.array([-1.0, 1, 1])
    for j in ARM:
        origin_mm, axis_r = TABLE_R[j]
        anchor, axis = _joint(model, data, f"{j}_{side}")
        np.testing.assert_allclose(anchor, COA + mirror * np.array(origin_mm) / 1000, atol=POS_TOL, err_msg=j)
        expected_axis = axis_r if side == "R" else AXES_L[j]
        np.testing.assert_allclose(axis, expected_axis, atol=AXIS_TOL, err_msg=j)
    tcp, rot = _site(model, data, f"{SIDES[side]}_tcp")
    np.testing.assert_allclose(tcp, COA + mirror * np.array(TCP_R_MM) / 1000, atol=POS_TOL)
    np.testing.assert_allclose(rot[:, 2], [0, 1, 0], atol=AXIS_TOL)  # approach +y


def test_zero_pose_shape(model):
    """Upper arm 310 mm (+20 mm), forearm 240 mm forward, elbow at 90 deg, wrist -> TCP 130 mm."""
    data = _fk(model)
    for side in SIDES.values():
        sh, _ = _site(model, data, f"{side}_shoulder")
        el, _ = _site(model, data, f"{side}_elbow")
        wr, _ = _site(model, data, f"{side}_wrist")
        tcp, _ = _site(model, data, f"{side}_tcp")
        assert np.linalg.norm(el - sh) == pytest.approx(math.hypot(0.310, 0.020), abs=1e-6)
        fore = wr - el
        assert fore[1] == pytest.approx(0.240, abs=1e-6)
        assert np.linalg.norm(fore) == pytest.approx(math.hypot(0.240, 0.0075), abs=1e-6)
        np.testing.assert_allclose(tcp - wr, [0, 0.130, 0], atol=1e-9)
        # upper arm tilted 15 deg outward in the frontal plane
        ua = el - sh
        out = ua[0] if side == "right" else -ua[0]
        assert math.degrees(math.atan2(out, -ua[2])) == pytest.approx(15.0, abs=1e-6)


# ---------------------------------------------------------------- Simox DH chain at random poses
@pytest.mark.parametrize("side", ["R", "L"])
def test_matches_simox_dh_chain(model, side):
    rng = np.random.default_rng(3)
    tcp_offset = None
    for trial in range(25):
        q_arm = [rng.uniform(*np.radians(LIMITS[side][j])) for j in ARM] if trial else [0.0] * 7
        hip = rng.uniform(-0.7, 0.7, size=2) if trial else np.zeros(2)
        q = {f"{j}_{side}": v for j, v in zip(ARM, q_arm)}
        q.update(HipPitch=hip[0], HipYaw=hip[1])
        data = _fk(model, q)
        frames, tcp_ref = simox_fk(side, q_arm, *hip)
        for j, frame in zip(ARM, frames):
            anchor, axis = _joint(model, data, f"{j}_{side}")
            np.testing.assert_allclose(anchor, frame[:3, 3], atol=1e-6, err_msg=j)
            np.testing.assert_allclose(axis, frame[:3, 2], atol=1e-6, err_msg=j)
        tcp, rot = _site(model, data, f"{SIDES[side]}_tcp")
        np.testing.assert_allclose(tcp, tcp_ref[:3, 3], atol=1e-6)
        # our TCP frame differs from the Simox TCP frame by a constant rotation
        rel = tcp_ref[:3, :3].T @ rot
        if tcp_offset is None:
            tcp_offset = rel
        np.testing.assert_allclose(rel, tcp_offset, atol=1e-6)


# ---------------------------------------------------------------- limits
@pytest.mark.parametrize("side", ["R", "L"])
def test_joint_ranges(model, side):
    for j in ARM:
        jid = model.joint(f"{j}_{side}").id
        assert model.jnt_limited[jid]
        np.testing.assert_allclose(model.jnt_range[jid], np.radians(LIMITS[side][j]), atol=1e-5, err_msg=j)


# ---------------------------------------------------------------- sites
def test_site_names_and_bodies(model):
    names = {model.site(i).name for i in range(model.nsite)}
    expected_bodies = {}
    for s, side in SIDES.items():
        expected_bodies.update(
            {
                f"{side}_shoulder": model.body(model.joint(f"Shoulder1_{s}").bodyid[0]).parentid[0],
                f"{side}_elbow": model.joint(f"Upperarm_{s}").bodyid[0],
                f"{side}_wrist": model.joint(f"Underarm_{s}").bodyid[0],
                f"{side}_tcp": model.joint(f"Wrist2_{s}").bodyid[0],
            }
        )
    assert set(expected_bodies) <= names
    for name, body in expected_bodies.items():
        assert model.site_bodyid[model.site(name).id] == body, name
    assert model.body(model.site_bodyid[model.site("right_elbow").id]).name == "Upperarm_R"
    assert model.body(model.site_bodyid[model.site("left_wrist").id]).name == "Underarm_L"
    assert model.body(model.site_bodyid[model.site("left_tcp").id]).name == "Wrist2_L"


def test_sites_at_joint_centres(model):
    data = _fk(model)
    for s, side in SIDES.items():
        for site, joint in (("shoulder", "Shoulder1"), ("elbow", "Elbow"), ("wrist", "Wrist1")):
            pos, _ = _site(model, data, f"{side}_{site}")
            anchor, _ = _joint(model, data, f"{joint}_{s}")
            np.testing.assert_allclose(pos, anchor, atol=1e-9)


def test_tcp_frame_convention(model):
    """z = approach (+y at zero pose), x = palm normal, y = z x x. The Simox hand's fingers curl
    towards -x of its base frame (EndArm), so at the zero pose the palms face up, 15 deg medially."""
    data = _fk(model)
    c, s = np.cos(np.radians(15)), np.sin(np.radians(15))
    for side, palm in (("left", (s, 0, c)), ("right", (-s, 0, c))):
        _, rot = _site(model, data, f"{side}_tcp")
        np.testing.assert_allclose(rot[:, 2], [0, 1, 0], atol=1e-9)
        np.testing.assert_allclose(rot[:, 0], palm, atol=1e-9)
        np.testing.assert_allclose(rot[:, 1], np.cross(rot[:, 2], rot[:, 0]), atol=1e-9)
        assert np.linalg.det(rot) == pytest.approx(1.0)


# ---------------------------------------------------------------- toml
def test_toml(model, desc):
    assert desc["name"] == "armar3"
    assert desc["title"] == "ARMAR-III"
    assert (TOML.parent / desc["model"]).resolve() == MJCF
    assert desc["extra_joints"] == ["HipPitch", "HipYaw"]
    assert desc["unlimited_joints"] == []
    joint_names = {model.joint(i).name for i in range(model.njnt)}
    for s, side in SIDES.items():
        chain = desc["arms"][side]["joints"]
        assert chain == [f"{j}_{s}" for j in ARM]
        assert set(chain) <= joint_names
        # proximal -> distal
        for a, b in zip(chain, chain[1:]):
            assert _is_descendant(model, model.joint(b).bodyid[0], model.joint(a).bodyid[0])
        mapping = desc["mapping"][side]
        assert set(mapping) == set(chain)
        for entry in mapping.values():
            assert set(entry) >= {"a", "b"}
    assert set(desc["extra_joints"]) <= joint_names


def test_home_pose(model, desc):
    home = desc["home"]
    all_joints = set(desc["extra_joints"]) | {
        j for side in SIDES.values() for j in desc["arms"][side]["joints"]
    }
    assert set(home) == all_joints
    for name, val in home.items():
        lo, hi = model.jnt_range[model.joint(name).id]
        assert lo <= val <= hi, name
    data = _fk(model, home)
    for side in SIDES.values():
        sh, _ = _site(model, data, f"{side}_shoulder")
        el, _ = _site(model, data, f"{side}_elbow")
        wr, _ = _site(model, data, f"{side}_wrist")
        ua = (el - sh) / np.linalg.norm(el - sh)
        assert ua[2] < -0.95  # upper arm hanging
        fa = (wr - el) / np.linalg.norm(wr - el)
        flex = math.degrees(math.acos(np.clip(ua @ fa, -1, 1)))
        assert 10 < flex < 60  # elbow somewhat bent
        assert wr[2] < el[2]
