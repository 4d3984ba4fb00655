"""`hlik run` end to end: the CLI, its errors, and the recording read back from disk."""

from __future__ import annotations

import re
import shutil
import subprocess

import numpy as np
import pyarrow as pa
import pytest
from rerun.chunk import RrdReader
from typer.testing import CliRunner

from conftest import ROBOTS
from hlik.cli import app
from hlik.robot.model import load_robot
from hlik.trajectory import load_trajectory


def _invoke(*args):
    return CliRunner().invoke(app, ["run", *args])


@pytest.fixture(scope="module")
def default_run(tmp_path_factory):
    """`hlik run` with no argument, from a fresh working directory."""
    cwd = tmp_path_factory.mktemp("cwd")
    with pytest.MonkeyPatch.context() as mp:
        mp.chdir(cwd)
        result = _invoke()
    assert result.exit_code == 0, result.output
    return cwd / "recordings" / "demo_pour_wipe_armar6_qp.rrd", result


def _chunks(path):
    """Entity -> list of non-static record batches, and the set of entities with static data."""
    temporal, static = {}, set()
    for chunk in RrdReader(path).stream().to_chunks():
        if chunk.is_static:
            static.add(chunk.entity_path)
        else:
            temporal.setdefault(chunk.entity_path, []).append(chunk.to_record_batch())
    return temporal, static


def _column(batches, name):
    """One column of record batches as a flat array; durations in seconds."""
    parts = []
    for batch in batches:
        col = batch.column(name)
        if pa.types.is_list(col.type):
            col = col.flatten()
        if pa.types.is_duration(col.type):
            parts.append(col.cast(pa.int64()).to_numpy() / 1e9)
        else:
            parts.append(col.to_numpy())
    return np.concatenate(parts)


def test_default_run_writes_recording_and_trajectory(default_run):
    rrd, result = default_run
    assert rrd.is_file() and rrd.with_suffix(".npz").is_file()
    assert sorted(p.name for p in rrd.parent.iterdir()) == [rrd.with_suffix(".npz").name, rrd.name]
    assert "fPOS mean" in result.stdout and str(rrd.name) in result.stdout
    traj = load_trajectory(rrd.with_suffix(".npz"))
    assert traj.robot == "armar6" and traj.solver == "qp"
    np.testing.assert_allclose(np.diff(traj.times), 0.01, atol=1e-9)  # --rate defaults to 100 Hz


def test_recording_reads_back(default_run):
    rrd, _ = default_run
    traj = load_trajectory(rrd.with_suffix(".npz"))
    robot = load_robot("armar6")
    temporal, static = _chunks(rrd)
    # every robot and human body with geometry moves, every joint and error has a curve
    bodies = {robot.model.body(b).name for b in set(robot.model.geom_bodyid) if b > 0}
    assert {f"/world/robot/bodies/{b}" for b in bodies} <= set(temporal)
    assert any(e.startswith("/world/human/bodies/") for e in temporal)
    assert {"/world/robot/target_paths", "/world/robot/tcp_paths", "/world/human/hand_paths"} <= static
    curves = {f"/plots/joints/{j}" for j in traj.joint_names}
    curves |= {f"/plots/{m}/{s}" for m in ("fPOS", "fORI") for s in ("left", "right")}
    assert curves <= set(temporal)
    for j, name in enumerate(traj.joint_names):
        batches = temporal[f"/plots/joints/{name}"]
        frames, values = _column(batches, "frame"), _column(batches, "Scalars:scalars")
        assert len(frames) == len(values) == traj.n_frames
        np.testing.assert_array_equal(values[np.argsort(frames)], traj.q[:, j])
    batches = temporal["/plots/fPOS/left"]
    order = np.argsort(_column(batches, "frame"))
    np.testing.assert_allclose(_column(batches, "time")[order], traj.times, atol=1e-9)
    for name in (
        "EEA",
        "SOA_x",
        "SOA_q",
        "HJL",
        "SYN",
        "MIS",
        "MJE",
        "HJA_r",
        "SYN_r",
        "EEA_r",
        "MAN_r",
        "fPOS",
    ):
        values = _column(temporal[f"/plots/metrics/{name}"], "Scalars:scalars")
        assert len(values) == traj.n_frames and np.all((values >= 0) & (values <= 1)), name
    assert RrdReader(rrd).recordings()[0].application_id == "hlik"
    assert len(RrdReader(rrd).blueprints()) == 1


def test_rerun_verifies_the_file(default_run):
    rrd, _ = default_run
    exe = shutil.which("rerun")
    assert exe, "the rerun CLI ships with rerun-sdk and must be on PATH"
    done = subprocess.run([exe, "rrd", "verify", str(rrd)], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr


def test_same_input_same_recording(default_run, tmp_path):
    rrd, _ = default_run
    again = tmp_path / "again.rrd"
    assert _invoke("--out", str(again)).exit_code == 0
    exe = shutil.which("rerun")
    # the data model is unordered: the SDK batches chunks on a timer, so their order varies under load
    compare = [exe, "rrd", "compare", "--unordered", str(rrd), str(again)]
    done = subprocess.run(compare, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr


@pytest.mark.parametrize("robot", ROBOTS)
def test_run_on_a_recorded_take(robot, takes, tmp_path):
    take = takes[ROBOTS.index(robot)]
    out = tmp_path / f"{robot}.rrd"
    result = _invoke(str(take), "--robot", robot, "--out", str(out), "--layout", "overlay")
    assert result.exit_code == 0, result.output
    traj = load_trajectory(out.with_suffix(".npz"))
    assert traj.robot == robot and np.all(np.isfinite(traj.q))
    temporal, static = _chunks(out)
    objects = [e for e in static if e.startswith("/world/objects/")]
    assert objects and all(e in temporal for e in objects)  # KIT objects drawn where their pose is known
    frames = _column(temporal["/plots/fORI/right"], "frame")
    assert len(frames) == traj.n_frames


def test_rate_option_resamples(takes, tmp_path):
    out = tmp_path / "r.rrd"
    assert _invoke(str(takes[0]), "--rate", "0", "--out", str(out)).exit_code == 0
    native = load_trajectory(out.with_suffix(".npz"))
    np.testing.assert_allclose(np.median(np.diff(native.times)), 0.1, rtol=1e-6)  # KIT takes are 10 Hz
    assert _invoke(str(takes[0]), "--rate", "50", "--out", str(out), "--force").exit_code == 0
    np.testing.assert_allclose(np.diff(load_trajectory(out.with_suffix(".npz")).times), 0.02, atol=1e-9)


@pytest.mark.parametrize(
    "args,pattern",
    [
        (["missing.xml"], r"missing\.xml: no such file"),
        (["--robot", "armar7"], r"unknown robot 'armar7'"),
        (["--solver", "magic"], r"unknown solver 'magic'; choose one of: jm"),
        (["--layout", "stacked"], r"unknown layout 'stacked'"),
        (["--rate", "-5"], r"--rate must be positive"),
        (["--out", "{tmp}/no/such/dir/x.rrd"], r"x\.rrd: output folder .* does not exist"),
        (["--out", "{tmp}"], r"is a folder"),
    ],
)
def test_bad_input_one_line_exit_2_nothing_written(args, pattern, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    result = _invoke(*[a.format(tmp=tmp_path) for a in args])
    assert result.exit_code == 2
    err = result.stderr.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert re.search(pattern, err), err
    assert not any(p.suffix in (".rrd", ".npz", ".tmp") for p in tmp_path.rglob("*"))


def test_malformed_motion_file(tmp_path):
    bad = tmp_path / "bad.xml"
    bad.write_text("<MMM version='2.0'><Motion name='x'>")
    result = _invoke(str(bad), "--out", str(tmp_path / "x.rrd"))
    assert result.exit_code == 2 and str(bad) in result.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.xml"]


def test_failed_recording_leaves_nothing(tmp_path, monkeypatch):
    import hlik.recording.write

    def broken(*_args, **_kwargs):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(hlik.recording.write, "_log", broken)
    out = tmp_path / "x.rrd"
    result = _invoke("--out", str(out))
    assert result.exit_code == 2 and "No space left" in result.stderr
    assert not any(p.suffix in (".rrd", ".tmp") for p in tmp_path.iterdir())


def test_summary_reports_where_the_hands_lag():
    from hlik.findings import LAG, lag_spans

    times = np.arange(50) * 0.01
    fpos = np.zeros((50, 2))
    fpos[10:20, 0] = 2 * LAG
    fpos[30:35] = 3 * LAG
    assert lag_spans(fpos, times) == "0.10-0.19 s (left), 0.30-0.34 s (both); 15 frames"
    assert lag_spans(np.zeros((50, 2)), times) == ""
    one = np.zeros((50, 2))
    one[18, 0] = 2 * LAG
    assert lag_spans(one, times) == "0.18 s (left); 1 frame"  # not "0.18-0.18 s", "1 frames"


def test_the_readmes_jm_errors_on_the_demo_are_current():
    """README "What you see": JM's mean hand errors on the demo per robot, as the sentence states
    them, within the last digit printed."""
    from pathlib import Path

    import hlik

    text = (Path(__file__).resolve().parents[1] / "README.md").read_text()
    sentence = " ".join(text[text.index("JM maps joint angles and ignores") :].split("That")[0].split())
    titles = {"ARMAR-III": "armar3", "2-Panda": "dual_panda", "ARMAR-6": "armar6"}
    stated = re.findall(r"(ARMAR-III|2-Panda|ARMAR-6) ([\d.]+) cm / ([\d.]+)°", sentence)
    assert len(stated) == 3, sentence
    for title, cm, deg in stated:
        ev = hlik.run(hlik.RunSpec(robot=titles[title], solver="jm")).evaluation
        assert 100 * ev.fpos.mean() == pytest.approx(float(cm), abs=0.06), title
        assert np.degrees(ev.fori.mean()) == pytest.approx(float(deg), abs=0.06), title
