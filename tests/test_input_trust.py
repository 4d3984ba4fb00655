"""Inputs hlik can trust (issue 15): criteria that difference unlimited joints as angles, and cache
entries (learned pieces, reachability maps) that are refitted when they do not prove themselves."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from conftest import data_file
from hlik.criteria import learned as learned_module
from hlik.criteria import registry
from hlik.criteria.learned import learn
from hlik.criteria.smoothness import ACCELERATION, JERK, MJE, VELOCITY, backward_difference, smoothness_terms
from hlik.criteria.synergy import MIS
from hlik.human.load import load_motion
from hlik.metrics import costs, speed_ratios, trajectory_sample
from hlik.problem.placement import mapped_placement
from hlik.retarget import retarget
from hlik.robot import reachability as reach_module
from hlik.robot.model import load_robot
from hlik.robot.reachability import reachability_map
from hlik.robot.state import robot_state
from hlik.solvers.frames import sample_at
from hlik.solvers.gradients import gradient
from hlik.util.cache import read_entry, write_entry

# A take whose ARMAR-6 elbow (an unlimited joint) passes pi between 4 and 5 s.
TAKE = "kit_bimanual/Close_files_motions_3072_Close1_aj_180_30h_08.xml"
TWO_PI = 2.0 * np.pi


@pytest.fixture(scope="module")
def armar6_jm():
    """ARMAR-6, its learned pieces and a JM trajectory of one second of a real take at 100 Hz."""
    robot = load_robot("armar6")
    motion = load_motion(data_file(TAKE), rate=100.0).crop(4.0, 5.0)
    # JM's joint angles do not depend on the placement; this one needs no reachability map
    return robot, learn(robot), retarget(motion, robot, "jm", mapped_placement(robot, motion))


def _unlimited(robot):
    return np.isinf(robot.lower)


def _motion_residuals(robot, learned, traj, q):
    """Residuals of everything that differences q over time: MIS, MJE (and its solver form) and the
    solvers' smoothness term, for every frame of ``traj`` with joint angles ``q``."""
    moved = replace(traj, q=q)
    sample, state = trajectory_sample(moved, moved.reference), robot_state(robot, q)
    ((smooth, _),) = smoothness_terms(robot, 0.3, 0.2, 0.1)
    mje = MJE(robot)
    return {
        "MIS": MIS(robot, learned.synergies).residual(state, sample),
        "MJE": mje.residual(state, sample),
        "MJE solver form": backward_difference(q, sample.history, mje.solver_stencil, mje.unlimited),
        "smoothness": smooth.residual(state, sample),
    }


def test_the_take_moves_an_unlimited_joint_across_pi(armar6_jm):
    """The trajectory the properties below use is no easy case: wrapping it makes a 2 pi jump."""
    robot, _, traj = armar6_jm
    u = _unlimited(robot)
    assert u.sum() == 6
    wrapped = np.pi - np.mod(np.pi - traj.q[:, u], TWO_PI)
    assert np.abs(np.diff(wrapped, axis=0)).max() > 6.0


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), reach=st.integers(1, 50))
def test_winding_unlimited_joints_by_whole_turns_changes_no_criterion(armar6_jm, seed, reach):
    """Adding 2 pi k (random k per frame and joint) to the unlimited joints gives the same poses, so
    every criterion's h, the speed ratios and the residuals of the motion terms stay the same."""
    robot, learned, traj = armar6_jm
    u = _unlimited(robot)
    q = traj.q.copy()
    q[:, u] += TWO_PI * np.random.default_rng(seed).integers(-reach, reach + 1, (len(q), u.sum()))
    before, after = costs(traj, robot, learned), costs(replace(traj, q=q), robot, learned)
    for name in before:
        np.testing.assert_allclose(after[name], before[name], rtol=1e-9, atol=1e-9, err_msg=name)
    np.testing.assert_allclose(speed_ratios(replace(traj, q=q), robot), speed_ratios(traj, robot), rtol=1e-9)
    want, got = _motion_residuals(robot, learned, traj, traj.q), _motion_residuals(robot, learned, traj, q)
    for name in want:
        np.testing.assert_allclose(got[name], want[name], rtol=1e-9, atol=1e-9, err_msg=name)


def test_wrapping_unlimited_joints_into_the_half_open_turn_changes_no_criterion(armar6_jm):
    robot, learned, traj = armar6_jm
    u = _unlimited(robot)
    q = traj.q.copy()
    q[:, u] = np.pi - np.mod(np.pi - q[:, u], TWO_PI)  # (-pi, pi]
    before, after = costs(traj, robot, learned), costs(replace(traj, q=q), robot, learned)
    for name in registry.human_likeness() + registry.functional():
        np.testing.assert_allclose(after[name], before[name], rtol=1e-9, atol=1e-9, err_msg=name)


def test_turns_that_are_not_whole_are_still_motion(armar6_jm):
    """The properties above could fail: steps of a fraction of a turn change MIS and MJE."""
    robot, learned, traj = armar6_jm
    u = _unlimited(robot)
    q = traj.q.copy()
    q[:, u] += np.random.default_rng(1).uniform(-0.5, 0.5, (len(q), u.sum()))
    before, after = costs(traj, robot, learned), costs(replace(traj, q=q), robot, learned)
    assert np.mean(after["MJE"]) > 10 * np.mean(before["MJE"])
    assert np.abs(after["MIS"] - before["MIS"]).max() > 0.1


@pytest.mark.parametrize("name", ["MIS", "MJE", "smoothness"])
def test_gradients_of_the_motion_terms_ignore_whole_turns(armar6_jm, name):
    """A solver's step from a wound configuration and history is the step from the plain one."""
    robot, learned, traj = armar6_jm
    term = (
        smoothness_terms(robot, 0.3, 0.2, 0.1)[0][0]
        if name == "smoothness"
        else registry.criterion(name, robot, learned)
    )
    u = _unlimited(robot)
    ref = trajectory_sample(traj, traj.reference)
    rng = np.random.default_rng(7)
    for k in (10, 50, 90):
        history = ref.history[k]
        turns = TWO_PI * rng.integers(-3, 4, (4, u.sum()))
        q_wound, history_wound = traj.q[k].copy(), history.copy()
        q_wound[u] += turns[0]
        history_wound[:, u] += turns[1:]
        h, grad = gradient(
            term,
            robot_state(robot, traj.q[k], jacobians=True),
            sample_at(traj.reference, traj.targets, k, history, ref.dt),
        )
        h_wound, grad_wound = gradient(
            term,
            robot_state(robot, q_wound, jacobians=True),
            sample_at(traj.reference, traj.targets, k, history_wound, ref.dt),
        )
        assert h_wound == pytest.approx(h, rel=1e-9, abs=1e-12)
        np.testing.assert_allclose(grad_wound, grad, rtol=1e-7, atol=1e-9)
        assert np.any(grad != 0.0)


@pytest.mark.parametrize("stencil", [VELOCITY, ACCELERATION, JERK])
def test_an_unlimited_joint_that_only_winds_rests(stencil):
    """Whole turns between samples are no motion of an unlimited joint, and motion of a limited one."""
    unlimited = np.array([True, False])
    turns = np.array([0.0, 3.0, -1.0, 2.0, 5.0, 1.0])
    q = np.stack([TWO_PI * turns + 0.3, TWO_PI * turns], axis=1)
    previous = np.stack([q[3 - k : 6 - k] for k in range(1, 4)], axis=1)
    d = backward_difference(q[3:], previous, stencil, unlimited)
    np.testing.assert_allclose(d[:, 0], 0.0, atol=1e-12)
    assert np.abs(d[:, 1]).max() > 1.0


# --- cache entries ---------------------------------------------------------------------------


def _only_entry(folder, pattern):
    found = sorted(folder.glob(pattern))
    assert len(found) == 1, found
    return found[0]


def _rewrite(path, change):
    with np.load(path, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    change(arrays)
    with open(path, "wb") as f:
        np.savez(f, **arrays)


def _scale(arrays):
    arrays["scale"] = arrays["scale"] * 1.5


def _zero_swivel(arrays):
    arrays["swivel_coef"] = np.zeros_like(arrays["swivel_coef"])


def _drop_key(arrays):
    for k in [k for k in arrays if k.startswith("entry.")]:
        del arrays[k]


@pytest.fixture(scope="module")
def learned_entries(tmp_path_factory):
    """ARMAR-6's learned pieces fitted into an empty cache, the bytes of its entry and of ARMAR-III's,
    and both robots' lambda_R (the second of a fit, which the tests below need not sample again)."""
    folder = tmp_path_factory.mktemp("learned-entries")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("HLIK_CACHE", str(folder))
        fresh = learn(load_robot("armar6"))
        entry = _only_entry(folder, "armar6-*.npz")
        other = learn(load_robot("armar3"))
    assert fresh.notes == ()
    scales = {"armar6": fresh.scale, "armar3": other.scale}
    return fresh, entry.name, entry.read_bytes(), _only_entry(folder, "armar3-*.npz").read_bytes(), scales


LEARNED_FAULTS = {
    "another robot's entry": (lambda path, other: path.write_bytes(other), "robot 'armar3', not 'armar6'"),
    "lambda_R scaled": (lambda path, other: _rewrite(path, _scale), "does not match its checksum"),
    "swivel regressor zeroed": (
        lambda path, other: _rewrite(path, _zero_swivel),
        "does not match its checksum",
    ),
    "no key (older hlik)": (lambda path, other: _rewrite(path, _drop_key), "has no key or checksum"),
    "truncated": (lambda path, other: path.write_bytes(path.read_bytes()[:3000]), "is truncated or damaged"),
    "empty": (lambda path, other: path.write_bytes(b""), "is empty"),
    "not an archive": (
        lambda path, other: path.write_bytes(b"\x93NUMPY garbage" * 50),
        "is not an .npz archive",
    ),
}


@pytest.mark.parametrize("fault", LEARNED_FAULTS)
def test_a_learned_entry_that_does_not_prove_itself_is_fitted_again(
    tmp_path, monkeypatch, learned_entries, fault
):
    """The entry is fitted again (once), with one note naming it and what is wrong; the result and
    the rewritten entry equal a fresh fit, and nothing else is left in the cache."""
    fresh, name, good, other, scales = learned_entries
    monkeypatch.setenv("HLIK_CACHE", str(tmp_path))
    fits = []  # lambda_R is the slow part of a fit: sampled once in the fixture, counted here
    monkeypatch.setattr(
        learned_module, "scale_factor", lambda robot: fits.append(robot.name) or scales[robot.name]
    )
    path = tmp_path / name
    path.write_bytes(good)
    corrupt, why = LEARNED_FAULTS[fault]
    corrupt(path, other)
    robot = load_robot("armar6")
    got = learn(robot)
    assert fits == ["armar6"]
    assert len(got.notes) == 1 and "\n" not in got.notes[0]
    assert got.notes[0].startswith(f"{path}: cache entry ") and why in got.notes[0], got.notes
    assert got.notes[0].endswith("; fitted again")
    again = learn(robot)
    assert fits == ["armar6"] and again.notes == ()  # the rewritten entry is whole and trusted
    for learned in (got, again):
        assert learned.scale == fresh.scale and learned.swivel_rms == fresh.swivel_rms
        np.testing.assert_array_equal(learned.swivel.coef, fresh.swivel.coef)
        for field in fresh.synergies.__dataclass_fields__:
            np.testing.assert_array_equal(getattr(learned.synergies, field), getattr(fresh.synergies, field))
    assert sorted(p.name for p in tmp_path.iterdir()) == [name]  # no temporary left


def test_a_folder_in_place_of_a_learned_entry_is_two_notes_and_a_fresh_fit(
    tmp_path, monkeypatch, learned_entries
):
    fresh, name, _, _, scales = learned_entries
    monkeypatch.setenv("HLIK_CACHE", str(tmp_path))
    monkeypatch.setattr(learned_module, "scale_factor", lambda robot: scales[robot.name])
    (tmp_path / name).mkdir()
    got = learn(load_robot("armar6"))
    assert [n.split(": ", 1)[0] for n in got.notes] == [str(tmp_path / name)] * 2
    assert "cache entry is unreadable" in got.notes[0] and "cannot write the cache entry" in got.notes[1]
    np.testing.assert_array_equal(got.synergies.basis, fresh.synergies.basis)
    assert got.scale == fresh.scale and not list(tmp_path.glob(".*"))  # no temporary left


@pytest.fixture(scope="module")
def reach_entries(tmp_path_factory):
    """A small reachability map of ARMAR-6 sampled into an empty cache, its entry, and ARMAR-III's."""
    folder = tmp_path_factory.mktemp("reach-entries")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("HLIK_CACHE", str(folder))
        fresh = reachability_map(load_robot("armar6"), n_samples=2000)
        entry = _only_entry(folder, "reach-armar6-*.npz")
        reachability_map(load_robot("armar3"), n_samples=2000)
        other = _only_entry(folder, "reach-armar3-*.npz")
    assert fresh.notes == ()
    return fresh, entry.name, entry.read_bytes(), other.read_bytes()


REACH_FAULTS = {
    "another robot's map": (lambda path, other: path.write_bytes(other), "robot 'armar3', not 'armar6'"),
    "counts zeroed": (
        lambda path, other: _rewrite(path, lambda a: a.update(counts=np.zeros_like(a["counts"]))),
        "does not match its checksum",
    ),
    "truncated": (lambda path, other: path.write_bytes(path.read_bytes()[:-100]), "is truncated or damaged"),
    "empty": (lambda path, other: path.write_bytes(b""), "is empty"),
}


@pytest.mark.parametrize("fault", REACH_FAULTS)
def test_a_reachability_entry_that_does_not_prove_itself_is_sampled_again(
    tmp_path, monkeypatch, reach_entries, fault
):
    fresh, name, good, other = reach_entries
    monkeypatch.setenv("HLIK_CACHE", str(tmp_path))
    samplings = []  # sampled once in the fixture (seeded: the same map), counted here
    monkeypatch.setattr(reach_module, "sample_map", lambda robot, n, **kw: samplings.append(n) or fresh)
    path = tmp_path / name
    path.write_bytes(good)
    corrupt, why = REACH_FAULTS[fault]
    corrupt(path, other)
    robot = load_robot("armar6")
    got = reachability_map(robot, n_samples=2000)
    assert samplings == [2000] and len(got.notes) == 1
    assert got.notes[0].startswith(f"{path}: cache entry ") and why in got.notes[0], got.notes
    assert got.notes[0].endswith("; sampled the map again")
    again = reachability_map(robot, n_samples=2000)  # read back from the rewritten entry
    assert samplings == [2000] and again.notes == ()
    np.testing.assert_array_equal(again.counts, fresh.counts)
    np.testing.assert_array_equal(again.origin, fresh.origin)
    assert (again.robot, again.cell, again.n_samples) == (fresh.robot, fresh.cell, fresh.n_samples)
    assert sorted(p.name for p in tmp_path.iterdir()) == [name]


arrays_strategy = st.dictionaries(
    st.text("abcdefgh._", min_size=1, max_size=6).filter(lambda k: not k.startswith("entry.")),
    st.lists(st.floats(allow_nan=False, allow_infinity=False), min_size=1, max_size=8).map(np.array),
    min_size=1,
    max_size=4,
)


@settings(max_examples=30, deadline=None)
@given(arrays=arrays_strategy, robot=st.sampled_from(["armar3", "armar6"]), data=st.data())
def test_an_entry_reads_back_as_written_and_any_changed_value_is_refused(
    tmp_path_factory, arrays, robot, data
):
    path = tmp_path_factory.mktemp("entry") / "x.npz"
    key = {"format": "test/1", "robot": robot}
    assert write_entry(path, arrays, key) is None
    back, problem = read_entry(path, key)
    assert problem is None and back is not None and set(back) == set(arrays)
    for k in arrays:
        np.testing.assert_array_equal(back[k], arrays[k])
    assert (
        read_entry(path, {**key, "robot": "dual_panda"})[1]
        == f"was written for robot {robot!r}, not 'dual_panda'"
    )
    name = data.draw(st.sampled_from(sorted(arrays)))
    i = data.draw(st.integers(0, len(arrays[name]) - 1))
    _rewrite(path, lambda a: a[name].__setitem__(i, np.nextafter(a[name][i], -a[name][i] or 1.0)))
    assert read_entry(path, key) == (None, "does not match its checksum (edited or damaged)")


def test_an_entry_that_cannot_be_written_is_a_note_not_an_error(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("")
    note = write_entry(blocker / "x.npz", {"a": np.zeros(3)}, {"format": "test/1"})
    assert note is not None and note.startswith(f"{blocker / 'x.npz'}: cannot write the cache entry")
    assert note.endswith("not cached") and "\n" not in note
