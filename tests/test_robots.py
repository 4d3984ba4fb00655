"""Robot descriptions, the joint mapping and its calibration (paper Sec. III-A, Table I)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from typer.testing import CliRunner

from hlik import load_motion
from hlik.calibrate import calibrate
from hlik.cli import app
from hlik.human import human_model
from hlik.motion import ARM_JOINTS
from hlik.robot import SITES, available_robots, load_robot

ROBOTS = ("armar3", "armar6", "dual_panda")
PI = np.pi
TABLE_I_PANDA = {  # paper Table I, 2-Panda (printed values)
    "left": ((-1, 1, -1, -1, -1, -1, 0), (0, -PI / 2, PI / 2, 0, -PI / 2, PI, 3 * PI / 4)),
    "right": ((1, 1, -1, -1, -1, 1, 0), (0, PI / 2, PI / 2, 0, PI / 2, PI, 3 * PI / 4)),
}


def test_bundled_robots():
    assert available_robots() == ROBOTS
    dofs = {r: load_robot(r).dof for r in ROBOTS}
    assert dofs == {"armar3": 16, "armar6": 16, "dual_panda": 14}
    assert "armar6" in repr(load_robot("armar6")) and "unlimited=6" in repr(load_robot("armar6"))


@pytest.mark.parametrize("name", ROBOTS)
def test_models_and_sites(name):
    r = load_robot(name)
    data = mujoco.MjData(r.model)
    data.qpos[:] = r.home
    mujoco.mj_kinematics(r.model, data)
    for side in ("left", "right"):
        ids = [r.site_id(side, s) for s in SITES]
        pos = data.site_xpos[ids]
        assert np.all(np.isfinite(pos))
        assert (pos[0, 0] < 0) == (side == "left")  # left arm on the robot's left (-x)
    home_in = (r.home >= r.lower - 1e-9) & (r.home <= r.upper + 1e-9)
    assert home_in.all(), [n for n, ok in zip(r.joint_names, home_in) if not ok]


def test_human_model_scales_with_height():
    a, b = human_model(1.0), human_model(1.8)
    da, db = mujoco.MjData(a), mujoco.MjData(b)
    for m, d in ((a, da), (b, db)):
        d.qpos[3] = 1.0
        mujoco.mj_kinematics(m, d)
    sa, sb = da.site("left_shoulder").xpos, db.site("left_shoulder").xpos
    assert np.allclose(sb, 1.8 * sa)
    assert sa[2] == pytest.approx(0.818)  # Winter: shoulder at 0.818 L
    assert sa[0] == pytest.approx(-0.110)


@pytest.mark.parametrize("name", ROBOTS)
def test_calibration_reproduces_stored_mapping(name):
    robot = load_robot(name)
    derived = calibrate(robot).mapping
    for m in robot.mapping.joints:
        d = derived.get(m.joint)
        assert (d.mmm, d.a) == (m.mmm, m.a), m.joint
        assert d.b == pytest.approx(m.b, abs=1e-5), m.joint
        assert (d.offset is None) == (m.offset is None), m.joint
        if m.offset:
            assert (d.offset.mmm, d.offset.gain) == (m.offset.mmm, pytest.approx(m.offset.gain))


def test_panda_calibration_is_table_i():
    cal = calibrate(load_robot("dual_panda")).mapping
    for side, (a, b) in TABLE_I_PANDA.items():
        for k in range(7):
            m = cal.get(f"{side}_joint{k + 1}")
            assert m.a == a[k] and m.b == pytest.approx(b[k], abs=1e-9) and m.offset is None
            if a[k]:
                # row 6, printed "w_x", is the joint that physically moves the Panda hand like
                # MMM wrist flexion (LWy) at the default pose; the printed a and b hold exactly
                assert m.mmm == ARM_JOINTS[side][6 if k == 5 else k]


def test_armar_offsets_follow_the_paper():
    """ARMAR-III: Shoulder2 held at its limit, the paper's β_A3 = -0.2417; ARMAR-6: Sho2 depends on s_x."""
    a3 = load_robot("armar3").mapping
    assert a3.get("Shoulder2_R").b == pytest.approx(-0.2417, abs=1e-4)
    a6 = load_robot("armar6").mapping
    for side in "LR":
        off = a6.get(f"Arm{side}3_Sho2").offset
        assert off.mmm == f"{side}Sx_joint" and 0.1 < off.gain < 0.25  # paper: 0.55/π = 0.175
        assert a6.get(f"Arm{side}1_Cla1").a == 0.0  # the clavicle has no MMM counterpart


@pytest.mark.parametrize("name", ROBOTS)
def test_mapping_of_recorded_take_is_finite(name, takes):
    robot = load_robot(name)
    m = load_motion(takes[0])
    mapped = robot.mapping.apply(m.joint_names, m.joints)
    assert set(mapped) == {j for s in robot.arm_joints.values() for j in s}
    assert all(np.all(np.isfinite(v)) and v.shape == (m.n_frames,) for v in mapped.values())


def test_single_joint_moves_match_on_panda():
    """Moving one mapped MMM joint moves the Panda arm the same way (segment directions)."""
    robot = load_robot("dual_panda")
    human = human_model(1.8)
    hd, rd = mujoco.MjData(human), mujoco.MjData(robot.model)
    names = ARM_JOINTS["left"] + ARM_JOINTS["right"]
    for k, joint in enumerate(names[:5]):
        q = np.zeros(14)
        q[[3, 10]] = PI / 2
        q[k] += 0.3
        hd.qpos[:] = 0
        hd.qpos[3] = 1
        for n, v in zip(names, q):
            hd.qpos[human.jnt_qposadr[human.joint(n).id]] = v
        mapped = robot.mapping.apply(names, q[None])
        rd.qpos[:] = robot.home
        for n, v in mapped.items():
            rd.qpos[robot.index(n)] = v[0]
        mujoco.mj_kinematics(human, hd)
        mujoco.mj_kinematics(robot.model, rd)

        def fore(model, data):
            e, w = data.site("left_elbow").xpos, data.site("left_wrist").xpos
            return (w - e) / np.linalg.norm(w - e)

        ang = np.degrees(np.arccos(np.clip(fore(human, hd) @ fore(robot.model, rd), -1, 1)))
        assert ang < 15.0, (joint, ang)  # Panda link offsets keep a few degrees


def test_cli_robots_info_calibrate():
    runner = CliRunner()
    out = runner.invoke(app, ["robots"])
    assert out.exit_code == 0 and "ARMAR-6" in out.output and "2-Panda" in out.output
    out = runner.invoke(app, ["info"])
    assert out.exit_code == 0 and "demo_pour_wipe" in out.output
    out = runner.invoke(app, ["calibrate", "armar3"])
    assert out.exit_code == 0 and "matches robots/armar3.toml" in out.output


def test_top_level_api():
    import hlik

    assert hlik.load_robot("armar6").title == "ARMAR-6"
    assert set(hlik.available_robots()) == set(ROBOTS)
