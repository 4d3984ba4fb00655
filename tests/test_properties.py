"""Properties that hold for any input: round trips, invariances, monotonicity (hypothesis)."""

from __future__ import annotations

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from hlik.criteria.functional import rotation_vector
from hlik.criteria.unified import logistic
from hlik.human.demo import demo_motion
from hlik.human.mmm_format import read_mmm, write_mmm
from hlik.problem.placement import Placement

FAST = settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
vectors = st.lists(st.floats(-3.0, 3.0), min_size=3, max_size=3).map(np.array)


@FAST
@given(rotvec=vectors, translation=vectors, points=st.lists(vectors, min_size=1, max_size=5))
def test_to_base_undoes_to_world(rotvec, translation, points):
    placement = Placement(Rotation.from_rotvec(rotvec).as_matrix(), translation)
    pos = np.stack(points)
    rot = Rotation.from_rotvec(pos).as_matrix()
    back_pos, back_rot = placement.to_base(*placement.to_world(pos, rot))
    np.testing.assert_allclose(back_pos, pos, atol=1e-9)
    np.testing.assert_allclose(back_rot, rot, atol=1e-9)
    np.testing.assert_allclose(Placement.from_matrix(placement.matrix).matrix, placement.matrix)


@FAST
@given(axis=vectors.filter(lambda v: np.linalg.norm(v) > 1e-3), angle=st.floats(0.0, np.pi - 2e-3))
def test_rotation_vector_matches_scipy(axis, angle):
    rotvec = axis / np.linalg.norm(axis) * angle
    np.testing.assert_allclose(rotation_vector(Rotation.from_rotvec(rotvec).as_matrix()), rotvec, atol=1e-9)


@FAST
@given(x0=st.floats(1e-5, 10.0), xs=st.lists(st.floats(0.0, 50.0), min_size=2, max_size=20))
def test_logistic_is_one_half_at_x0_and_never_rises(x0, xs):
    assert logistic(x0, x0) == 0.5
    xs = np.sort(np.array(xs))
    assert np.all(np.diff(logistic(xs, x0)) <= 0.0)
    assert np.all((logistic(xs, x0) >= 0.0) & (logistic(xs, x0) <= 1.0))


def test_mirroring_twice_is_the_identity():
    motion = demo_motion().crop(0.0, 1.0)
    twice = motion.mirrored().mirrored()
    np.testing.assert_allclose(twice.joints, motion.joints, atol=1e-12)
    np.testing.assert_allclose(twice.root_position, motion.root_position, atol=1e-12)
    np.testing.assert_allclose(twice.root_rotation, motion.root_rotation, atol=1e-12)
    assert twice.joint_names == motion.joint_names


@FAST
@given(start=st.floats(0.0, 5000.0), rate=st.sampled_from([10.0, 25.0, 100.0, 120.0, 240.0]))
def test_mmm_files_round_trip_exactly_at_any_time_base(tmp_path_factory, start, rate):
    motion = demo_motion().crop(0.0, 0.2).resample(rate)
    from dataclasses import replace

    motion = replace(motion, times=motion.times - motion.times[0] + start)
    path = tmp_path_factory.mktemp("mmm") / "m.xml"
    write_mmm(motion, path)
    back = read_mmm(path)
    np.testing.assert_array_equal(back.times, motion.times)
    np.testing.assert_array_equal(back.joints, motion.joints)
    np.testing.assert_allclose(back.root_position, motion.root_position, atol=1e-12)
