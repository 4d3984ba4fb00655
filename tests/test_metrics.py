"""The unified metric, the joint-space and synergy criteria, learned pieces and `hlik evaluate`."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from conftest import ROBOTS
from hlik import load_motion, load_robot, retarget
from hlik.cli import app
from hlik.criteria import registry, unified
from hlik.criteria.joints import human_limits, mapped_pose
from hlik.criteria.learned import learn
from hlik.human.demo import demo_motion
from hlik.metrics import evaluate
from hlik.robot.model import mapped_configuration
from hlik.util.errors import HlikError
from hlik.util.paths import cache_dir

TABLE_III = {  # name: (x0, inverse weight), paper Table III
    "EEA": (0.3, 20), "SOA_x": (0.2, 20), "SOA_q": (0.34, 20), "HJL": (0.48, 15), "SYN": (0.12, 15),
    "MIS": (0.49, 5), "MJE": (2e-4, 5), "HJA_r": (0.35, 30), "SYN_r": (0.47, 30), "EEA_r": (0.1, 20),
    "MAN_r": (1.9, 5),
}  # fmt: skip
TABLE_II = {  # paper Table II (MJE is part of OPT, gamma 1)
    "EEA": 4, "SOA_x": 10, "SOA_q": 2, "HJL": 1, "SYN": 6, "MIS": 1, "HJA_r": 2, "SYN_r": 2, "EEA_r": 6,
    "MAN_r": 0.5,
}  # fmt: skip


def test_logistic_and_weights():
    assert registry.human_likeness() == tuple(TABLE_III)
    for name, (x0, inverse) in TABLE_III.items():
        cls = registry.criterion_class(name)
        assert (cls.x0, cls.weight) == (x0, pytest.approx(1 / inverse)), name
        assert cls.gamma == TABLE_II.get(name, 1.0), name
        assert unified.logistic(x0, x0) == pytest.approx(0.5)
        assert unified.logistic(0.0, x0) > 0.99 and unified.logistic(2 * x0, x0) < 0.01
        assert np.all(np.diff(unified.logistic(np.linspace(0, 3 * x0, 50), x0)) < 0)
    m = dict.fromkeys(registry.human_likeness(), 0.7)
    assert unified.hierarchical(m) == pytest.approx(0.7)
    assert unified.combined(1.0, 0.0) == 0.5


@pytest.mark.parametrize("robot", ROBOTS)
def test_reference_criteria_vanish_on_the_mapped_human(robot):
    r = load_robot(robot)
    motion = demo_motion().crop(0, 2)
    hja = mapped_pose(r, mapped_configuration(r, motion))
    q = np.tile(r.home, (motion.n_frames, 1))
    q[:, hja.idx] = hja.centre
    np.testing.assert_allclose(hja.residual(q), 0.0, atol=1e-12)
    np.testing.assert_allclose(learn(r).synergies.syn_r_residual(q, q), 0.0, atol=1e-12)
    assert np.abs(hja.residual(q + 0.1)).max() > 0.05


def test_human_limits_map_the_mmm_range():
    r = load_robot("dual_panda")  # Table I mapping without dynamic offsets
    band = human_limits(r)
    assert np.all(band.half > 0)
    lo, hi = band.centre - band.half, band.centre + band.half
    # the mapped range of every joint is an interval of the MMM range's length
    m = r.mapping.get("right_joint4")  # elbow: a = -1 on REx in [0, 2.79]
    k = list(r.index([r.joint_names[i] for i in band.idx])).index(r.index("right_joint4"))
    assert sorted((m.a * 0 + m.b, m.a * 2.79253 + m.b)) == pytest.approx([lo[k], hi[k]], abs=1e-5)


@pytest.mark.parametrize("robot", ROBOTS)
def test_jm_on_a_recorded_take_scores_in_unit_interval(robot, takes):
    r = load_robot(robot)
    traj = retarget(load_motion(takes[2], rate=100.0), r)
    for scenario in ("pose", "relative"):
        ev = evaluate(traj, r, learn(r), scenario=scenario)
        for k, h in ev.h.items():
            assert h.shape == (traj.n_frames,) and np.all(np.isfinite(h)), k
        for k, m in ev.m.items():
            assert 0.0 <= m <= 1.0, k
        assert 0.0 <= ev.m_hl <= 1.0 and 0.0 <= ev.m_f <= 1.0
        assert ev.m_hl_f == pytest.approx(0.5 * (ev.m_hl + ev.m_f))
        assert set(ev.m) == set(registry.human_likeness()) | set(unified.FUNCTIONAL_X0[scenario])
    # JM follows the mapped human wherever the limits allow
    assert ev.m["HJA_r"] > 0.95 and ev.m["SYN_r"] > 0.95


def test_learned_is_cached_by_robot_and_corpus(tmp_path):
    r = load_robot("dual_panda")
    first = learn(r)
    files = sorted(cache_dir().glob("dual_panda-*.npz"))
    assert files
    again = learn(r)
    np.testing.assert_array_equal(again.synergies.basis, first.synergies.basis)
    assert again.scale == first.scale and again.swivel_rms == first.swivel_rms
    assert 0.5 < first.synergies.explained.sum() <= 1.0 and first.synergies.basis.shape[0] == 5
    corpus = tmp_path / "corpus"
    corpus.mkdir()
    demo = demo_motion().crop(0, 6)
    from hlik.human.mmm_format import write_mmm

    write_mmm(demo, corpus / "short.xml")
    other = learn(r, corpus)
    assert len(sorted(cache_dir().glob("dual_panda-*.npz"))) == len(files) + 1
    assert not np.allclose(other.synergies.mean, first.synergies.mean)
    with pytest.raises(HlikError, match="no such folder or file for the corpus"):
        learn(r, tmp_path / "missing")
    (tmp_path / "empty").mkdir()
    with pytest.raises(HlikError, match="no motion files"):
        learn(r, tmp_path / "empty")


def test_evaluate_cli(tmp_path, takes):
    traj = retarget(load_motion(takes[0], rate=100.0), load_robot("armar3"))
    path = traj.save(tmp_path / "t.npz")
    result = CliRunner().invoke(app, ["evaluate", str(path)])
    assert result.exit_code == 0, result.output
    assert all(k in result.stdout for k in ("EEA", "MAN_r", "m_hl", "fPOS"))
    result = CliRunner().invoke(app, ["evaluate", str(path), "--json", "--scenario", "relative"])
    data = json.loads(result.stdout)
    assert set(data["metrics"]) == set(registry.human_likeness())
    assert set(data["functional"]) == {"fJLA", "fPOS_off", "fORI_off", "fPOS", "fORI"}
    assert all(set(v) == {"h", "m"} for v in data["metrics"].values())
    assert data["m_hl_f"] == pytest.approx(0.5 * (data["m_hl"] + data["m_f"]))
    bad = CliRunner().invoke(app, ["evaluate", str(tmp_path / "missing.npz")])
    assert bad.exit_code == 2 and "missing.npz: no such file" in bad.stderr
    bad = CliRunner().invoke(app, ["evaluate", str(path), "--scenario", "other"])
    assert bad.exit_code == 2 and "unknown scenario" in bad.stderr


def test_costs_in_chunks_equal_costs_in_one_pass(monkeypatch, takes):
    """Chunks bound the memory of long takes; the history at each chunk's start carries over."""
    import hlik.metrics as metrics

    r = load_robot("armar6")
    traj = retarget(load_motion(takes[0], rate=100.0).crop(1.0, 2.5), r, solver="jm")
    learned = learn(r)
    whole = metrics.costs(traj, r, learned)
    monkeypatch.setattr(metrics, "COST_CHUNK", 37)
    chunked = metrics.costs(traj, r, learned)
    for name, h in whole.items():
        np.testing.assert_allclose(chunked[name], h, rtol=1e-12, atol=1e-15, err_msg=name)


def test_score_curves_of_motion_follow_the_motion_and_still_average_to_the_score(cut_take):
    """On the QP's Cut take the per-frame MJE score flips by more than 0.3 between frames in a
    tenth of the frames or more (its jerk sits near x0); over 0.2 s (21 frames) it flips in none,
    every curve still averages to its m_i, and the criteria that are not of motion are unchanged."""
    from hlik.criteria import registry
    from hlik.solvers.qp import QPSettings, qp_solver

    r = load_robot("dual_panda")
    learned = learn(r)
    motion = load_motion(cut_take, rate=100.0).crop(1.0, 4.0)
    traj = retarget(motion, r, qp_solver(QPSettings(criteria=("SYN", "HJA_r"))), learned=learned)
    ev = evaluate(traj, r, learned)
    raw, shown = ev.curves(), ev.curves(21)
    flips = lambda c: np.mean(np.abs(np.diff(c)) > 0.3)  # noqa: E731
    assert flips(raw["MJE"]) > 0.1, flips(raw["MJE"])
    assert flips(shown["MJE"]) == 0.0 and flips(shown["MIS"]) == 0.0
    for name, curve in shown.items():
        assert np.mean(curve) == pytest.approx(ev.m[name], abs=1e-12), name
        if not registry.criterion_class(name).motion:
            np.testing.assert_array_equal(curve, raw[name])
    with pytest.raises(ValueError, match="odd"):
        ev.curves(4)
