"""Long takes: the recording is written chunk by chunk with bounded memory and shows the same for
any chunking; the trajectory file stays an exact, plain ``.npz``.

Long takes are made in memory from a real KIT take, played forward and backward (never written
into the repository); outputs go to tmp_path.
"""

from __future__ import annotations

import shutil
import subprocess
import tracemalloc
import zipfile
from dataclasses import replace

import numpy as np
import pyarrow as pa
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from rerun.chunk import RrdReader

from hlik.criteria.learned import learn
from hlik.human.load import load_motion
from hlik.human.motion import HumanMotion
from hlik.metrics import evaluate
from hlik.problem.placement import placement_from_spec
from hlik.recording import write_recording
from hlik.retarget import retarget
from hlik.robot.model import load_robot
from hlik.trajectory import Trajectory, load_trajectory


def looped(motion: HumanMotion, frames: int) -> HumanMotion:
    """``motion`` played forward, backward, forward ... for ``frames`` frames at its own period."""
    n = motion.n_frames
    walk = np.arange(frames) % (2 * n - 2)
    index = np.where(walk < n, walk, 2 * n - 2 - walk)
    period = float(np.median(np.diff(motion.times)))
    return replace(motion.frames(index), times=motion.times[0] + period * np.arange(frames), markers={})


@pytest.fixture(scope="module")
def armar6():
    return load_robot("armar6")


@pytest.fixture(scope="module")
def cut(cut_take):
    """The Cut take at 100 Hz: 1061 frames."""
    return load_motion(cut_take, rate=100.0)


def _trajectory(motion: HumanMotion, robot) -> Trajectory:
    # placed on the human's shoulders: the reachability maps of the default rule cost seconds
    return retarget(motion, robot, "jm", placement_from_spec("shoulders", robot, motion))


def _content(path):
    """Entity -> static batches (as text, any order) and entity -> time-varying rows sorted by frame,
    without Rerun's row ids, which differ between any two files."""
    static: dict[str, list[str]] = {}
    batches: dict[str, list[pa.RecordBatch]] = {}
    for chunk in RrdReader(path).stream().to_chunks():
        batch = chunk.to_record_batch()
        batch = batch.drop_columns([n for n in batch.schema.names if n.endswith("RowId")])
        if chunk.is_static:
            static.setdefault(chunk.entity_path, []).append(repr(batch.to_pylist()))
        else:
            batches.setdefault(chunk.entity_path, []).append(batch)
    static.pop("/__properties", None)  # the recording's start time: the wall clock
    temporal = {e: pa.Table.from_batches(b).sort_by("frame") for e, b in batches.items()}
    return {e: sorted(v) for e, v in static.items()}, temporal, sum(map(len, batches.values()))


def test_chunked_recording_shows_the_same_as_one_chunk(cut, armar6, tmp_path):
    traj = _trajectory(cut, armar6)
    curves = evaluate(traj, armar6, learn(armar6)).curves()
    whole = write_recording(tmp_path / "whole.rrd", traj, armar6, metrics=curves, chunk_frames=10**6)
    # 97 does not divide 1061: the last chunk is short; objects are drawn where their pose is known
    chunked = write_recording(tmp_path / "chunked.rrd", traj, armar6, metrics=curves, chunk_frames=97)
    static_a, temporal_a, n_a = _content(whole)
    static_b, temporal_b, n_b = _content(chunked)
    assert static_a == static_b
    assert temporal_a.keys() == temporal_b.keys()
    for entity, table in temporal_a.items():
        assert table.equals(temporal_b[entity]), entity
    n_chunks = -(-traj.n_frames // 97)
    assert n_a == len(temporal_a) and n_b == n_chunks * len(temporal_b)
    # every frame once per drawn body, with its time
    body = temporal_b["/world/robot/bodies/base"]
    np.testing.assert_array_equal(body.column("frame").to_numpy(), np.arange(traj.n_frames))
    seconds = body.column("time").cast(pa.int64()).to_numpy() / 1e9
    np.testing.assert_allclose(seconds, traj.times, atol=1e-9)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["chunked.rrd", "whole.rrd"]
    exe = shutil.which("rerun")
    assert exe, "the rerun CLI ships with rerun-sdk and must be on PATH"
    done = subprocess.run([exe, "rrd", "verify", str(chunked)], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr


@pytest.fixture(scope="module")
def short_run(cut, armar6, tmp_path_factory):
    """Half a second of the Cut take, retargeted, its per-frame scores and the content of its
    recording written in one chunk."""
    traj = _trajectory(cut.crop(2.0, 2.5), armar6)
    curves = evaluate(traj, armar6, learn(armar6)).curves()
    whole = write_recording(tmp_path_factory.mktemp("short") / "whole.rrd", traj, armar6, metrics=curves)
    return traj, curves, _content(whole)


@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(chunk_frames=st.integers(1, 60))
def test_any_chunking_shows_the_same(short_run, armar6, tmp_path, chunk_frames):
    traj, curves, (static, temporal, _) = short_run
    path = write_recording(tmp_path / "chunked.rrd", traj, armar6, metrics=curves, chunk_frames=chunk_frames)
    chunked_static, chunked, _ = _content(path)
    assert chunked_static == static and chunked.keys() == temporal.keys()
    assert all(table.equals(chunked[entity]) for entity, table in temporal.items())


def test_recording_refuses_bad_arguments_and_leaves_nothing(short_run, armar6, tmp_path):
    traj, curves, _ = short_run
    with pytest.raises(ValueError, match="chunk_frames must be positive"):
        write_recording(tmp_path / "x.rrd", traj, armar6, chunk_frames=0)
    n = traj.n_frames
    with pytest.raises(ValueError, match=rf"metric 'SYN': \({n - 1},\) values for {n} frames"):
        write_recording(tmp_path / "x.rrd", traj, armar6, metrics={**curves, "SYN": curves["SYN"][1:]})
    assert list(tmp_path.iterdir()) == []


def _writer_peak(traj: Trajectory, robot, path) -> int:
    """Peak bytes NumPy and Python allocate while the recording is written."""
    tracemalloc.start()
    try:
        write_recording(path, traj, robot, chunk_frames=500)
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def _frame_bytes(traj: Trajectory) -> float:
    """Bytes a trajectory holds per frame (its arrays)."""
    arrays = [traj.q, traj.tcp_pos, traj.tcp_rot, traj.targets.pos, traj.targets.rot, traj.motion.joints]
    arrays += [traj.reference.q_map, traj.reference.manip, traj.motion.root_rotation]
    for obj in traj.motion.objects.values():
        arrays += [obj.position, obj.rotation, *obj.markers.values()]
    return sum(a.nbytes for a in arrays) / traj.n_frames


def test_recording_memory_does_not_grow_with_the_take(cut, armar6, tmp_path):
    short = _trajectory(looped(cut, 2000), armar6)
    long = _trajectory(looped(cut, 8000), armar6)
    small, large = (_writer_peak(t, armar6, tmp_path / f"{t.n_frames}.rrd") for t in (short, long))
    # Drawing every frame at once held (T, bodies) poses of the human and the robot: 1.5 kB a frame,
    # 3.9 times the peak for 4 times the frames. Chunk by chunk, only the static part grows (the
    # object-frame marker positions a box is fitted to, the hand paths).
    per_frame = _frame_bytes(long)
    growth = (large - small) / (long.n_frames - short.n_frames)
    assert growth < 0.25 * per_frame, (growth, per_frame)
    assert large < 0.25 * per_frame * long.n_frames, (large, per_frame)


def test_trajectory_file_is_a_plain_npz_and_exact(cut, armar6, tmp_path):
    traj = _trajectory(cut, armar6)
    path = traj.save(tmp_path / "t.npz")
    with zipfile.ZipFile(path) as z:  # stored: deflate would save ~13 % for ~50 times the write time
        assert {i.compress_type for i in z.infolist()} == {zipfile.ZIP_STORED}
        stored = sum(i.file_size for i in z.infolist())
    assert path.stat().st_size < 1.01 * stored
    back = load_trajectory(path)
    for name in ("times", "q", "tcp_pos", "tcp_rot"):
        np.testing.assert_array_equal(getattr(back, name), getattr(traj, name))
    np.testing.assert_array_equal(back.reference.manip, traj.reference.manip)
    np.testing.assert_array_equal(back.motion.joints, traj.motion.joints)
