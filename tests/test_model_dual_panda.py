"""2-Panda model (robots/mjcf/dual_panda.xml, robots/dual_panda.toml) vs kinematics.md §4, §9.

Checks the Panda modified-DH chain and limits, the README site rules, and that the paper's Table I
(q_panda = a * q_mmm + b) holds for the mounting: at q0 = b (the MMM zero pose mapped) the arms hang
straight down, joint axes equal a * (MMM axis), and the TCP frame equals the MMM hand frame.
"""

from pathlib import Path

import mujoco
import numpy as np
import pytest
import tomllib

ROOT = Path(__file__).resolve().parents[1]
XML = ROOT / "robots/mjcf/dual_panda.xml"
TOML = ROOT / "robots/dual_panda.toml"
PI = np.pi
SIDES = ("left", "right")

# kinematics.md §4.1: modified DH (Craig) a, d, alpha per joint, and the flange.
DH = [
    (0.0, 0.333, 0.0),
    (0.0, 0.0, -PI / 2),
    (0.0, 0.316, PI / 2),
    (0.0825, 0.0, PI / 2),
    (-0.0825, 0.384, -PI / 2),
    (0.0, 0.0, PI / 2),
    (0.088, 0.0, PI / 2),
]
FLANGE_D = 0.107
TCP_D = 0.107 + 0.1034
LIMITS = [
    (-2.8973, 2.8973),
    (-1.7628, 1.7628),
    (-2.8973, 2.8973),
    (-3.0718, -0.0698),
    (-2.8973, 2.8973),
    (-0.0175, 3.7525),
    (-2.8973, 2.8973),
]
MENAGERIE_HOME = [0.0, 0.0, 0.0, -1.57079, 0.0, 1.57079, -0.7853]

# Table I (kinematics.md §9): MMM s_x, s_y, s_z, e_x, e_z, w_x, w_z (= MMM Wy) -> joints 1..7, with
# joint 7's b a half-turn below the printed 3pi/4: hlik's TCP frame is turned by it (robots/dual_panda.toml
# says why; test_tcp_half_turn checks that the hand is the same).
B7_PRINTED = 3 * PI / 4
TABLE_I = {
    "left": (
        [-1, 1, -1, -1, -1, -1, 0],
        [0, -PI / 2, PI / 2, 0, -PI / 2, PI, B7_PRINTED - PI],
    ),
    "right": (
        [1, 1, -1, -1, -1, 1, 0],
        [0, PI / 2, PI / 2, 0, PI / 2, PI, B7_PRINTED - PI],
    ),
}
MMM_JOINTS = {
    # Row 6 (printed "w_x") moves the Panda like MMM's wrist flexion Wy (see the joint-axis test);
    # `hlik calibrate dual_panda` derives exactly this, with Table I's printed a and b.
    "left": ["LSx_joint", "LSy_joint", "LSz_joint", "LEx_joint", "LEz_joint", "LWy_joint", None],
    "right": ["RSx_joint", "RSy_joint", "RSz_joint", "REx_joint", "REz_joint", "RWy_joint", None],
}
# MMM joint axes in world at zero pose (both arms), in Table I order.
EX, EY, EZ = np.eye(3)
MMM_AXES = [EX, EY, EZ, EX, EZ, EX, EY]


def mdh(a, d, alpha, theta):
    ca, sa, ct, st = np.cos(alpha), np.sin(alpha), np.cos(theta), np.sin(theta)
    return np.array(
        [
            [ct, -st, 0.0, a],
            [st * ca, ct * ca, -sa, -d * sa],
            [st * sa, ct * sa, ca, d * ca],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )


def dh_frames(q):
    """Frames 1..7 and the flange relative to the Panda base (link0)."""
    t = np.eye(4)
    out = []
    for (a, d, alpha), th in zip(DH, q, strict=True):
        t = t @ mdh(a, d, alpha, th)
        out.append(t.copy())
    out.append(t @ mdh(0.0, FLANGE_D, 0.0, 0.0))
    return out


@pytest.fixture(scope="module")
def model():
    return mujoco.MjModel.from_xml_path(str(XML))


def jid(m, name):
    return mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name)


def body_pose(m, d, name):
    i = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, name)
    t = np.eye(4)
    t[:3, :3] = d.xmat[i].reshape(3, 3)
    t[:3, 3] = d.xpos[i]
    return t


def site(m, d, name):
    i = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, name)
    assert i >= 0, name
    return d.site_xpos[i].copy(), d.site_xmat[i].reshape(3, 3).copy()


def posed(m, q_by_side):
    d = mujoco.MjData(m)
    for side, q in q_by_side.items():
        for k, v in enumerate(q):
            d.qpos[m.jnt_qposadr[jid(m, f"{side}_joint{k + 1}")]] = v
    mujoco.mj_kinematics(m, d)
    return d


def q0():
    return {side: TABLE_I[side][1] for side in SIDES}


def test_joints_and_limits(model):
    m = model
    names = [m.joint(i).name for i in range(m.njnt)]
    assert names == [f"{s}_joint{k}" for s in SIDES for k in range(1, 8)]
    assert m.nq == 14
    for s in SIDES:
        for k, (lo, hi) in enumerate(LIMITS):
            j = jid(m, f"{s}_joint{k + 1}")
            assert m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE
            assert m.jnt_limited[j]
            np.testing.assert_allclose(m.jnt_range[j], (lo, hi), atol=1e-12)


def test_root_body_and_sites(model):
    m = model
    assert m.body(1).name == "base" and m.body_parentid[1] == 0
    for s in SIDES:
        for seg, body in (
            ("shoulder", "link0"),  # body before joint1 (first shoulder joint)
            ("elbow", "link3"),  # body of joint3 (last shoulder joint)
            ("wrist", "link5"),  # body of joint5 (forearm rotation)
            ("tcp", "link7"),  # body of joint7 (last arm joint)
        ):
            i = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, f"{s}_{seg}")
            assert i >= 0
            assert m.body(m.site_bodyid[i]).name == f"{s}_{body}"
    visual = m.geom_group == 1  # collision geoms (group 3): tests/test_collision.py
    assert all(m.geom_contype[visual] == 0) and all(m.geom_conaffinity[visual] == 0)


@pytest.mark.parametrize("side", SIDES)
@pytest.mark.parametrize("q", [MENAGERIE_HOME, [0.0] * 7, [0.3, -0.5, 1.0, -2.0, 0.7, 1.9, -1.2]])
def test_dh_chain(model, side, q):
    m = model
    d = posed(m, {side: q})
    base = body_pose(m, d, f"{side}_link0")
    inv = np.linalg.inv(base)
    ref = dh_frames(q)
    for k in range(7):
        rel = inv @ body_pose(m, d, f"{side}_link{k + 1}")
        np.testing.assert_allclose(rel, ref[k], atol=1e-9, err_msg=f"{side}_link{k + 1}")
    # sites at the DH joint centres: shoulder = frame 2, elbow = frame 4, wrist = frame 6
    for seg, k in (("shoulder", 1), ("elbow", 3), ("wrist", 5)):
        p, _ = site(m, d, f"{side}_{seg}")
        np.testing.assert_allclose((inv @ np.r_[p, 1])[:3], ref[k][:3, 3], atol=1e-9)
    # TCP 0.1034 m beyond the flange along its z
    p, r = site(m, d, f"{side}_tcp")
    np.testing.assert_allclose((inv @ np.r_[p, 1])[:3], (ref[6] @ [0, 0, TCP_D, 1])[:3], atol=1e-9)
    np.testing.assert_allclose(base[:3, :3].T @ r[:, 2], ref[7][:3, 2], atol=1e-9)


def test_mounting_position(model):
    m = model
    d = posed(m, q0())
    for s, sign in (("left", -1), ("right", 1)):
        base = body_pose(m, d, f"{s}_link0")
        np.testing.assert_allclose(base[:3, 3], [sign * 0.06, 0, 1.47], atol=1e-12)
        np.testing.assert_allclose(base[:3, 2], [sign, 0, 0], atol=1e-12)  # base z laterally out
        p, _ = site(m, d, f"{s}_shoulder")
        np.testing.assert_allclose(p, [sign * 0.393, 0, 1.47], atol=1e-12)


@pytest.mark.parametrize("side", SIDES)
def test_q0_arm_hangs_down(model, side):
    """(1) at q0 = b the elbow and wrist lie below the shoulder (elbow 0.0825 m forward)."""
    m = model
    d = posed(m, q0())
    sh, _ = site(m, d, f"{side}_shoulder")
    el, _ = site(m, d, f"{side}_elbow")
    wr, _ = site(m, d, f"{side}_wrist")
    tcp, _ = site(m, d, f"{side}_tcp")
    np.testing.assert_allclose(el - sh, [0, 0.0825, -0.316], atol=1e-9)
    np.testing.assert_allclose(wr - sh, [0, 0, -0.7], atol=1e-9)
    medial = 1.0 if side == "left" else -1.0
    np.testing.assert_allclose(tcp - sh, [medial * 0.088, 0, -(0.7 + TCP_D)], atol=1e-9)


@pytest.mark.parametrize("side", SIDES)
def test_q0_axes_match_table_i(model, side):
    """(2) joint i axis = a_i * MMM axis at q0 = b, joints 1..5 exactly as Table I pairs them."""
    m = model
    d = posed(m, q0())
    a, _ = TABLE_I[side]
    axes = [d.xaxis[jid(m, f"{side}_joint{k + 1}")] for k in range(7)]
    for k in range(5):
        np.testing.assert_allclose(axes[k], a[k] * MMM_AXES[k], atol=1e-9, err_msg=f"joint{k + 1}")
    # Joint 6: Table I pairs it with w_x (+x), but at q = b its axis is parallel to joint 2's
    # (both along base y, so +-y for ANY mounting that satisfies joint 2): it equals
    # a_6 * (MMM wrist y axis) and is perpendicular to w_x. Documented deviation; no mounting
    # can fix it.
    assert abs(np.dot(axes[5], axes[1])) == pytest.approx(1.0, abs=1e-9)
    assert abs(np.dot(axes[5], EX)) < 1e-9
    np.testing.assert_allclose(axes[5], a[5] * EY, atol=1e-9)
    # Joint 7 (a = 0, held at 3pi/4) rolls about the forearm.
    np.testing.assert_allclose(axes[6], -EZ, atol=1e-9)


@pytest.mark.parametrize("side", SIDES)
def test_q0_tcp_frame_is_mmm_hand_frame(model, side):
    """(3) TCP z = (0, 0, -1), x = palm normal (+x left, -x right) at q0 = b."""
    m = model
    d = posed(m, q0())
    _, r = site(m, d, f"{side}_tcp")
    palm = EX if side == "left" else -EX
    np.testing.assert_allclose(r[:, 2], -EZ, atol=1e-9)
    np.testing.assert_allclose(r[:, 0], palm, atol=1e-9)
    np.testing.assert_allclose(r[:, 1], np.cross(r[:, 2], r[:, 0]), atol=1e-9)


def test_toml(model):
    m = model
    with TOML.open("rb") as f:
        cfg = tomllib.load(f)
    assert cfg["name"] == "dual_panda" and cfg["title"] == "2-Panda"
    assert (TOML.parent / cfg["model"]).resolve() == XML
    assert cfg["extra_joints"] == [] and cfg["unlimited_joints"] == []
    for s in SIDES:
        joints = [f"{s}_joint{k}" for k in range(1, 8)]
        assert cfg["arms"][s]["joints"] == joints
        a, b = TABLE_I[s]
        mapping = cfg["mapping"][s]
        assert list(mapping) == joints
        for k, name in enumerate(joints):
            entry = mapping[name]
            assert entry["a"] == float(a[k]) and entry["b"] == pytest.approx(b[k], abs=1e-6)
            assert entry.get("mmm") == MMM_JOINTS[s][k]
            assert "offset" not in entry
    home = cfg["home"]
    assert set(home) == {f"{s}_joint{k}" for s in SIDES for k in range(1, 8)}
    for name, v in home.items():
        lo, hi = m.jnt_range[jid(m, name)]
        assert lo <= v <= hi, name
    # home keyframe in the MJCF equals [home]
    key = m.key("home").qpos
    for name, v in home.items():
        assert key[m.jnt_qposadr[jid(m, name)]] == pytest.approx(v, abs=1e-15)


def test_home_is_table_i_of_relaxed_pose():
    """[home] = Table I applied to MMM zero pose with elbows flexed 90 deg (e_x = pi/2)."""
    with TOML.open("rb") as f:
        cfg = tomllib.load(f)
    for s in SIDES:
        a, b = TABLE_I[s]
        mmm = [0.0, 0.0, 0.0, PI / 2, 0.0, 0.0, 0.0]
        for k in range(7):
            want = a[k] * mmm[k] + b[k]
            assert cfg["home"][f"{s}_joint{k + 1}"] == pytest.approx(want, abs=1e-15)


@pytest.mark.parametrize("side", SIDES)
def test_tcp_half_turn(model, side):
    """Joint 7 at b (-pi/4) and at Table I's printed 3pi/4 put the TCP at the same place with its frame
    turned a half-turn about the approach axis, and the Franka Hand's geometry (palm and two finger
    boxes) on the same places: the half-turn changes nothing a gripper could tell."""
    q = np.zeros(model.nq)
    for k, v in enumerate(TABLE_I[side][1]):
        q[model.jnt_qposadr[jid(model, f"{side}_joint{k + 1}")]] = v
    printed = q.copy()
    printed[model.jnt_qposadr[jid(model, f"{side}_joint7")]] = B7_PRINTED
    data = mujoco.MjData(model)
    tcp = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, f"{side}_tcp")
    hand = [
        mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, f"{side}_{g}")
        for g in ("palm", "finger_a", "finger_b")
    ]

    def pose(qpos):
        data.qpos[:] = qpos
        mujoco.mj_kinematics(model, data)
        # a box is the same box turned a half-turn about any of its axes: compare |R|
        boxes = sorted(
            (tuple(np.round(data.geom_xpos[g], 9)), tuple(np.round(np.abs(data.geom_xmat[g]), 9)))
            for g in hand
        )
        return data.site_xpos[tcp].copy(), data.site_xmat[tcp].reshape(3, 3).copy(), boxes

    p0, r0, boxes0 = pose(q)
    p1, r1, boxes1 = pose(printed)
    np.testing.assert_allclose(p0, p1, atol=1e-12)
    np.testing.assert_allclose(r0.T @ r1, np.diag([-1.0, -1.0, 1.0]), atol=1e-12)
    for k in (0, 1):  # positions, then |R|
        np.testing.assert_allclose([b[k] for b in boxes0], [b[k] for b in boxes1], atol=1e-9)
