"""ARMAR-6 model (robots/mjcf/armar6.xml, robots/armar6.toml) against kinematics.md §3 and §9."""

from pathlib import Path

import mujoco
import numpy as np
import pytest

try:
    import tomllib
except ModuleNotFoundError:  # Python < 3.11
    import tomli as tomllib

ROBOTS_DIR = Path(__file__).resolve().parents[1] / "robots"
MJCF = ROBOTS_DIR / "mjcf/armar6.xml"
TOML = ROBOTS_DIR / "armar6.toml"

NAMES = ["Cla1", "Sho1", "Sho2", "Sho3", "Elb1", "Elb2", "Wri1", "Wri2"]
LEFT = [f"ArmL{i}_{n}" for i, n in enumerate(NAMES, 1)]
RIGHT = [f"ArmR{i}_{n}" for i, n in enumerate(NAMES, 1)]
UNLIMITED = {"Sho1", "Sho3", "Elb2"}
LIMITS = {  # URDF column of §3.1, both sides
    "Cla1": (-1.3962634, 1.3962634),
    "Sho2": (-0.24, 3.1),
    "Elb1": (0.0, 2.51),
    "Wri1": (-0.64, 0.64),
    "Wri2": (-1.52, 1.52),
}
# Zero-pose FK of §3.2, left arm, torso frame (m)
FK_LEFT = {
    "shoulder": (-0.380, 0.0, 0.178),
    "elbow": (-0.584, 0.055, -0.177),
    "wrist": (-0.766, 0.055, -0.492),
    "palm": (-0.836, 0.055, -0.613),
}
TCP_BEYOND_PALM = 0.07  # §9
PALM_FROM_WRIST = 0.14  # IAI hand_joint
TORSO_Z = 1.195  # top of the URDF torso joint's range (0.830..1.195 m)
TOL = 2e-3
MIRROR = np.diag([-1.0, 1.0, 1.0])  # sagittal plane x = 0
# q_right = MIRROR_SIGN * q_left mirrors the pose (ArmarX home pose signs, §3.1)
MIRROR_SIGN = np.array([-1, -1, 1, -1, 1, -1, -1, 1.0])
HOME_L = [0.0368, 0.8399, 0.1120, 0.1789, 1.3174, -0.0780, 0.0814, 0.1718]
HOME_R = [-0.0368, -0.8394, 0.1116, -0.1790, 1.3195, 0.0783, -0.0811, 0.1719]


@pytest.fixture(scope="module")
def model():
    return mujoco.MjModel.from_xml_path(str(MJCF))


@pytest.fixture()
def data(model):
    return mujoco.MjData(model)


def fk(model, data, q=None):
    data.qpos[:] = 0.0 if q is None else q
    mujoco.mj_kinematics(model, data)
    return data


def torso(model, data):
    return data.xpos[model.body("torso").id].copy()


def site(model, data, name):
    return data.site_xpos[model.site(name).id].copy()


def site_mat(model, data, name):
    return data.site_xmat[model.site(name).id].reshape(3, 3).copy()


def anchor(model, data, joint):
    return data.xanchor[model.joint(joint).id].copy()


def axis(model, data, joint):
    return data.xaxis[model.joint(joint).id].copy()


def qpos_of(model, values):
    q = np.zeros(model.nq)
    for name, v in values.items():
        q[model.jnt_qposadr[model.joint(name).id]] = v
    return q


def random_q(model, rng):
    q = np.empty(model.nq)
    for j in range(model.njnt):
        lo, hi = model.jnt_range[j] if model.jnt_limited[j] else (-np.pi, np.pi)
        q[model.jnt_qposadr[j]] = rng.uniform(lo, hi)
    return q


# ---------------------------------------------------------------- structure


def test_joints_and_chain(model):
    assert model.nq == 16 and model.nv == 16 and model.njnt == 16
    names = [model.joint(j).name for j in range(model.njnt)]
    assert sorted(names) == sorted(LEFT + RIGHT)
    for chain in (LEFT, RIGHT):
        bodies = [model.jnt_bodyid[model.joint(j).id] for j in chain]
        assert len(set(bodies)) == 8, "one hinge per body"
        for parent, child in zip(bodies, bodies[1:], strict=False):
            assert model.body_parentid[child] == parent, "proximal -> distal"
        for j in chain:
            assert model.jnt_type[model.joint(j).id] == mujoco.mjtJoint.mjJNT_HINGE
        # the Cla1 body hangs off the fixed torso
        assert model.body(model.body_parentid[bodies[0]]).name == "torso"


def test_base_and_torso_fixed(model, data):
    base = model.body("base")
    assert base.parentid[0] == 0 and model.body_jntnum[base.id] == 0
    assert model.body_jntnum[model.body("torso").id] == 0
    fk(model, data)
    np.testing.assert_allclose(data.xpos[base.id], 0.0, atol=1e-12)
    np.testing.assert_allclose(torso(model, data), [0, 0, TORSO_Z], atol=1e-12)
    # shoulders at about 1.37 m above the floor
    for side in ("left", "right"):
        assert site(model, data, f"{side}_shoulder")[2] == pytest.approx(1.373, abs=TOL)


def test_limits(model):
    for chain in (LEFT, RIGHT):
        for j, short in zip(chain, NAMES, strict=True):
            jid = model.joint(j).id
            if short in UNLIMITED:
                assert not model.jnt_limited[jid], j
            else:
                assert model.jnt_limited[jid], j
                np.testing.assert_allclose(model.jnt_range[jid], LIMITS[short], atol=1e-6)


def test_site_names_and_bodies(model):
    expected = {"shoulder": "Cla1", "elbow": "Sho3", "wrist": "Elb2", "tcp": "Wri2"}
    for side, chain in (("left", LEFT), ("right", RIGHT)):
        by_short = dict(zip(NAMES, chain, strict=True))
        for seg, short in expected.items():
            s = model.site(f"{side}_{seg}")
            assert model.site_bodyid[s.id] == model.jnt_bodyid[model.joint(by_short[short]).id]


# ---------------------------------------------------------------- zero-pose FK (§3.2)


def test_zero_pose_fk_left(model, data):
    fk(model, data)
    t = torso(model, data)
    for j in LEFT[1:4]:
        np.testing.assert_allclose(anchor(model, data, j) - t, FK_LEFT["shoulder"], atol=TOL)
    for j in LEFT[4:6]:
        np.testing.assert_allclose(anchor(model, data, j) - t, FK_LEFT["elbow"], atol=TOL)
    for j in LEFT[6:8]:
        np.testing.assert_allclose(anchor(model, data, j) - t, FK_LEFT["wrist"], atol=TOL)
    for seg in ("shoulder", "elbow", "wrist"):
        np.testing.assert_allclose(site(model, data, f"left_{seg}") - t, FK_LEFT[seg], atol=TOL)
    # palm frame = 0.07 m back from the TCP along the approach
    tcp = site(model, data, "left_tcp")
    palm = tcp - TCP_BEYOND_PALM * site_mat(model, data, "left_tcp")[:, 2]
    np.testing.assert_allclose(palm - t, FK_LEFT["palm"], atol=TOL)


def test_zero_pose_axes(model, data):
    """Sho1 along the clavicle (15 deg up), Sho2 || forward, Sho3 along the upper arm (30 deg)."""
    fk(model, data)
    c15, s15 = np.cos(np.radians(15)), np.sin(np.radians(15))
    np.testing.assert_allclose(axis(model, data, "ArmL2_Sho1"), [-c15, 0, s15], atol=1e-6)
    np.testing.assert_allclose(abs(axis(model, data, "ArmL3_Sho2")[1]), 1.0, atol=1e-6)
    upper = site(model, data, "left_elbow") - site(model, data, "left_shoulder")
    sho3 = axis(model, data, "ArmL4_Sho3")
    # the Sho3 axis is the upper-arm axis (the 55 mm elbow offset is perpendicular to it)
    assert np.linalg.norm(np.cross(sho3, [-0.5, 0, -np.sqrt(3) / 2])) < 1e-6
    assert upper @ sho3 == pytest.approx(0.409, abs=1e-4)
    wri2 = axis(model, data, "ArmL8_Wri2")
    np.testing.assert_allclose(wri2, [np.sqrt(3) / 2, 0, -0.5], atol=1e-6)


def test_right_is_mirror_of_left(model, data):
    """As on the real robot: FK_right(MIRROR_SIGN q) = mirror of FK_left(q), exactly, for any q."""
    rng = np.random.default_rng(6)
    lq = model.jnt_qposadr[[model.joint(j).id for j in LEFT]]
    rq = model.jnt_qposadr[[model.joint(j).id for j in RIGHT]]
    for k in range(21):
        q = np.zeros(model.nq)
        if k:
            q[lq] = rng.uniform(-1.2, 1.2, 8)
        q[rq] = MIRROR_SIGN * q[lq]
        fk(model, data, q)
        for seg in ("shoulder", "elbow", "wrist", "tcp", "hand_mount"):
            np.testing.assert_allclose(
                site(model, data, f"right_{seg}"), MIRROR @ site(model, data, f"left_{seg}"), atol=1e-9
            )
        left, right = site_mat(model, data, "left_tcp"), site_mat(model, data, "right_tcp")
        # approach and palm normal are vectors: mirrored; y = z x x flips
        np.testing.assert_allclose(right, MIRROR @ left @ np.diag([1.0, -1.0, 1.0]), atol=1e-9)


def test_armarx_home_is_mirror_symmetric(model, data):
    """The published ArmarX home pose (left and right values as printed) is a mirror image to < 2 mm."""
    values = dict(zip(LEFT, HOME_L)) | dict(zip(RIGHT, HOME_R))
    fk(model, data, qpos_of(model, values))
    for seg in ("elbow", "wrist", "tcp"):
        d = site(model, data, f"right_{seg}") - MIRROR @ site(model, data, f"left_{seg}")
        assert np.linalg.norm(d) < 2e-3, seg


# ---------------------------------------------------------------- TCP frame


def test_tcp_frame_convention(model, data):
    rng = np.random.default_rng(0)
    for q in [None] + [random_q(model, rng) for _ in range(20)]:
        fk(model, data, q)
        for side, chain in (("left", LEFT), ("right", RIGHT)):
            r = site_mat(model, data, f"{side}_tcp")
            np.testing.assert_allclose(r.T @ r, np.eye(3), atol=1e-9)
            assert np.linalg.det(r) == pytest.approx(1.0, abs=1e-9)
            d = site(model, data, f"{side}_tcp") - site(model, data, f"{side}_wrist")
            assert np.linalg.norm(d) == pytest.approx(PALM_FROM_WRIST + TCP_BEYOND_PALM, abs=1e-9)
            np.testing.assert_allclose(r[:, 2], d / np.linalg.norm(d), atol=1e-9)  # z = approach
            # wrist semantics of the chosen palm normal: Wri2 (+-87 deg) is flexion/extension,
            # its axis lies in the palm plane
            assert abs(r[:, 0] @ axis(model, data, chain[7])) < 1e-9


def test_palm_normal_zero_pose(model, data):
    """Decision (documented in the MJCF header): at the zero pose both palms face forward (+y) and
    the Wri1 axis is parallel to the palm normal (radial/ulnar deviation)."""
    fk(model, data)
    for side, chain in (("left", LEFT), ("right", RIGHT)):
        x = site_mat(model, data, f"{side}_tcp")[:, 0]
        np.testing.assert_allclose(x, [0, 1, 0], atol=1e-9)
        assert abs(x @ axis(model, data, chain[6])) == pytest.approx(1.0, abs=1e-9)


# ---------------------------------------------------------------- toml


@pytest.fixture(scope="module")
def desc():
    with TOML.open("rb") as f:
        return tomllib.load(f)


def test_toml(desc, model):
    assert desc["name"] == "armar6" and desc["title"] == "ARMAR-6"
    assert (TOML.parent / desc["model"]).resolve() == MJCF
    assert desc["extra_joints"] == []
    assert desc["arms"]["left"]["joints"] == LEFT
    assert desc["arms"]["right"]["joints"] == RIGHT
    unlimited = {model.joint(j).name for j in range(model.njnt) if not model.jnt_limited[j]}
    assert set(desc["unlimited_joints"]) == unlimited
    assert len(desc["unlimited_joints"]) == 6
    for side, chain in (("left", LEFT), ("right", RIGHT)):
        mapping = desc["mapping"][side]
        assert set(mapping) == set(chain)
        for entry in mapping.values():
            assert set(entry) >= {"a", "b"}


def test_toml_home(desc, model, data):
    home = desc["home"]
    assert set(home) == set(LEFT + RIGHT)
    for j, v in home.items():
        jid = model.joint(j).id  # raises if the joint does not exist
        if model.jnt_limited[jid]:
            lo, hi = model.jnt_range[jid]
            assert lo <= v <= hi, j
    # the published values, each pair averaged so that the home pose is exactly mirror-symmetric
    np.testing.assert_allclose([home[j] for j in LEFT], HOME_L, atol=1.1e-3)
    np.testing.assert_allclose([home[j] for j in RIGHT], HOME_R, atol=1.1e-3)
    np.testing.assert_array_equal([home[j] for j in RIGHT], MIRROR_SIGN * [home[j] for j in LEFT])
    # at home the left hand is below the shoulder, the palm normal points medially (+x)
    fk(model, data, qpos_of(model, home))
    assert site(model, data, "left_tcp")[2] < site(model, data, "left_shoulder")[2] - 0.5
    assert site_mat(model, data, "left_tcp")[0, 0] > 0.3
