"""Inputs that would exhaust memory, the stack or patience, or leak a file's content (issue 30):
each is one line naming the file, before anything heavy is read."""

from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np
import pytest

from hlik.human.keypoints import read_keypoints
from hlik.solvers.qp import QPSettings
from hlik.solvers.stack_file import load_stack
from hlik.util import arrayfile
from hlik.util.errors import HlikError, MotionFormatError, SettingsError

KEYPOINTS = "".join(
    f"{s}_{p} = {i}\n"
    for i, (s, p) in enumerate((s, p) for p in ("shoulder", "elbow", "wrist") for s in ("left", "right"))
)


def _claiming(path: Path, shape: tuple[int, ...]) -> None:
    """An .npy whose header claims ``shape`` with (almost) no data behind it."""
    with open(path, "wb") as fp:
        np.lib.format.write_array_header_1_0(fp, {"descr": "<f8", "fortran_order": False, "shape": shape})
        fp.write(b"\0" * 64)


def _description(tmp_path: Path, data: str) -> Path:
    desc = tmp_path / "take.toml"
    desc.write_text(f'data = "{data}"\narray = "joint_pos"\nrate = 30\n[keypoints]\n{KEYPOINTS}')
    return desc


@pytest.mark.parametrize("suffix", [".npy", ".npz"])
def test_an_array_header_claiming_terabytes_is_refused_before_reading(tmp_path, suffix):
    _claiming(tmp_path / "huge.npy", (10**7, 10**6))
    if suffix == ".npz":
        with zipfile.ZipFile(tmp_path / "huge.npz", "w") as archive:
            archive.write(tmp_path / "huge.npy", "joint_pos.npy")
    with pytest.raises(MotionFormatError, match=r"header claims shape \(10000000, 1000000\)") as e:
        read_keypoints(_description(tmp_path, f"huge{suffix}"))
    assert "\n" not in str(e.value) and str(e.value).startswith(str(tmp_path / "take.toml"))


def test_an_npz_member_that_inflates_beyond_the_limit_is_refused(tmp_path, monkeypatch):
    """A zip bomb (2.9 GB of zeros in 2.8 MB): the member's inflated size is read from the zip's
    directory, not by inflating it; the limit is lowered here so the test stays small."""
    monkeypatch.setattr(arrayfile, "MAX_BYTES", 10**6)
    with zipfile.ZipFile(tmp_path / "bomb.npz", "w", compression=zipfile.ZIP_DEFLATED) as archive:
        with archive.open("joint_pos.npy", "w") as fp:
            np.save(fp, np.zeros((20_000, 6, 3)))  # 2.9 MB of zeros, a few kB deflated
    assert (tmp_path / "bomb.npz").stat().st_size < 50_000
    with pytest.raises(MotionFormatError, match="array 'joint_pos' inflates to 0.0029 GB"):
        read_keypoints(_description(tmp_path, "bomb.npz"))


def test_a_take_over_the_frame_limit_is_refused_before_any_fit(tmp_path):
    """4 h at 100 Hz (1.44 M frames, over hlik's 10^6) was fitted for hours before being refused."""
    _claiming(tmp_path / "long.npy", (1_440_000, 6, 3))
    with pytest.raises(MotionFormatError, match="1440000 frames, more than hlik's 1000000; crop the take"):
        read_keypoints(_description(tmp_path, "long.npy"))


@pytest.mark.parametrize("secret", ["root:x:0:0:root:/root:/bin/bash", "SECRET=hunter2"])
def test_a_data_file_that_is_not_numbers_is_not_quoted(tmp_path, secret):
    """A description pointing at /etc/shadow or /proc/self/environ quoted its first line."""
    (tmp_path / "private.txt").write_text(secret + "\n")
    desc = tmp_path / "take.toml"
    desc.write_text(f'data = "private.txt"\nrate = 30\n[keypoints]\n{KEYPOINTS}')
    with pytest.raises(MotionFormatError, match=r"private.txt: not a table of numbers \(row 1") as e:
        read_keypoints(desc)
    assert secret not in str(e.value) and secret.split(":")[0] not in str(e.value).split("private.txt")[-1]


def test_a_toml_nested_thousands_deep_is_one_line(tmp_path):
    path = tmp_path / "deep.toml"
    path.write_text("a = " + "[" * 3000 + "]" * 3000 + "\n")
    with pytest.raises(SettingsError, match="nested too deeply"):
        load_stack(path)


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("position_cost", 1e300, r"position_cost must be a finite number in \[0, 1e\+06\]"),
        ("max_iter", 10**12, r"max_iter must be a whole number in \[1, 100000\]"),
    ],
)
def test_settings_have_upper_bounds(tmp_path, field, value, message):
    """A weight of 1e300 overflowed the objective (10 lines of RuntimeWarning) and ran on."""
    with pytest.raises(SettingsError, match=message):
        QPSettings(**{field: value})
    path = tmp_path / "stack.toml"
    path.write_text(f"[qp]\n{field} = {value!r}\n".replace("e+300", "e300"))
    with pytest.raises(HlikError, match=field):
        load_stack(path).settings("qp")


def test_a_trajectory_whose_header_claims_terabytes_is_one_line(tmp_path):
    """hlik evaluate / export / replay read a trajectory .npz: its members' headers are checked
    before any array is read (before, a 73 TiB allocation ended in a traceback)."""
    from typer.testing import CliRunner

    from hlik.cli import app

    _claiming(tmp_path / "q.npy", (10**7, 10**6))
    with zipfile.ZipFile(tmp_path / "t.npz", "w") as archive:
        archive.write(tmp_path / "q.npy", "q.npy")
    for command in ("evaluate", "export", "replay"):
        result = CliRunner().invoke(app, [command, str(tmp_path / "t.npz")])
        assert result.exit_code == 2, result.output
        assert "array 'q': its header claims shape (10000000, 1000000)" in result.output
        assert result.output.count("\n") == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["q.npy", "t.npz"]  # nothing written


@pytest.mark.parametrize(
    ("table", "message"),
    [
        ("[qp.gamma]\nHJA_r = 1e300", r"\[qp.gamma\] HJA_r must be a finite number in \[0, 1e\+06\]"),
        ("[gamma]\nHJA_r = 1e300", r"\[gamma\] HJA_r must be a finite number in \[0, 1e\+06\]"),
        ("[qp.gamma]\nHJA_rr = 1", r"\[qp.gamma\]: unknown criteria HJA_rr \(did you mean 'HJA_r'\?\)"),
        ("[qp.robot.armar6]\norientation_cost = 1e300", r"\[qp.robot.armar6\] orientation_cost must be"),
    ],
)
def test_a_stack_names_the_table_of_a_bad_gamma_or_robot_weight(tmp_path, table, message):
    """A gamma of 1e300 was accepted and failed every frame; a robot's table was named [qp]."""
    path = tmp_path / "stack.toml"
    path.write_text(table + "\n")
    with pytest.raises(SettingsError, match=message):
        load_stack(path)
    with pytest.raises(SettingsError, match="gamma HJA_r must be a finite number in"):
        QPSettings(gamma={"HJA_r": 1e300})
