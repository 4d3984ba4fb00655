"""``hlik replay`` (issue 31): a trajectory that keeps the limits is followed by the simulated robot
under a torque controller within the motors' efforts; the same path played faster is not."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from typer.testing import CliRunner

from hlik import load_motion, load_robot, retarget
from hlik.cli import app
from hlik.replay import FOLLOWED, commanded, reference, replay
from hlik.util.paths import demo_motion_path


@pytest.fixture(scope="module")
def demo():
    return load_motion(demo_motion_path(), rate=100).crop(2.0, 3.5)


@pytest.mark.parametrize("name", ["armar3", "armar6", "dual_panda"])
def test_a_limit_keeping_run_replays_within_a_centimetre(demo, name):
    """The QP plans within 0.9 of the efforts; the feedback may touch a limit for a few frames
    (2-Panda's first two; ARMAR-III's 1 N m wrists against the model's joint damping, which the
    QP does not plan for), and the hands stay within a centimetre all the same."""
    robot = load_robot(name)
    result = replay(retarget(demo, robot, "qp"), robot)
    assert result.followed() == 1.0 and np.max(result.deviation) < FOLLOWED
    assert np.mean(result.saturated.any(axis=1)) < 0.1 and result.speed_ratio.max() < 1.05
    assert not any(result.contacts)


def test_the_same_path_played_four_times_faster_is_not_followed(demo):
    """Four times faster needs sixteen times the accelerations: the torques saturate, the joints
    pass their speed limits, and the hands fall behind."""
    robot = load_robot("dual_panda")
    traj = retarget(demo, robot, "qp")
    fast = dataclasses.replace(traj, times=traj.times[0] + (traj.times - traj.times[0]) / 4)
    result = replay(fast, robot)
    assert result.saturated.any() and result.followed() < 0.99
    assert result.deviation.max() > FOLLOWED
    said = "\n".join(result.lines())
    assert "joints at their effort limit: none" not in said
    assert result.verdict().startswith("NOT executable as commanded")


def test_the_reference_keeps_the_trajectory_s_own_accelerations(demo):
    """The controller's reference is C1 and asks for no acceleration the executable checks did
    not see: its accelerations are the second differences, its velocity continuous, and it passes
    within a dt^2/8 of the frames."""
    from hlik.executable import controller_checks

    robot = load_robot("armar6")
    traj = retarget(demo, robot, "qp")
    q, velocity, dt = commanded(traj, robot)
    checked = controller_checks(traj, robot).acceleration
    for k in range(1, len(q) - 2):
        pos, vel, acc = reference(q, velocity, dt, k, 0.0)
        np.testing.assert_allclose(acc, checked[k], atol=1e-9)
        assert np.all(np.abs(pos - q[k]) <= np.abs(checked[k]) * dt**2 / 8 + 1e-12)
        before = reference(q, velocity, dt, k - 1, 1.0 - 1e-9)[1]
        np.testing.assert_allclose(vel, before, atol=1e-6)


def test_hlik_replay_reports_per_hand_and_says_whether_it_follows(tmp_path):
    runner = CliRunner()
    out = tmp_path / "qp.rrd"
    assert (
        runner.invoke(app, ["run", "--robot", "dual_panda", "--solver", "qp", "-o", str(out)]).exit_code == 0
    )
    result = runner.invoke(app, ["replay", str(out.with_suffix(".npz"))])
    assert result.exit_code == 0, result.output
    assert "left TCP off the commanded one" in result.output and "right TCP" in result.output
    assert "the simulated robot follows the commanded motion within 1 cm" in result.output
    # the replay's own recording: the simulated robot over the commanded one, its TCPs' distance
    recording = tmp_path / "qp_replay.rrd"
    assert recording.is_file() and f"rerun {recording}" in result.output
    from rerun.chunk import RrdReader

    entities = {chunk.entity_path for chunk in RrdReader(recording).stream().to_chunks()}
    assert any(e.startswith("/world/robot/simulated/") for e in entities)
    assert {"/plots/fPOS/simulated_left", "/plots/fPOS/simulated_right"} <= entities
    again = runner.invoke(app, ["replay", str(out.with_suffix(".npz"))])
    assert again.exit_code == 2 and "exists; pass --force" in again.output
