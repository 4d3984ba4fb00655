"""A misspelt key in any TOML hlik reads is refused, naming the file, the table and the closest key
(issue 30: ``subject_scael = 0.9`` and ``placment = "mapped"`` were ignored without a word)."""

from __future__ import annotations

import re
import sys

import pytest

from hlik.robot.model import KEYS, TABLE_KEYS, load_robot
from hlik.util.errors import HlikError, RobotError
from hlik.util.paths import robots_dir

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

ROBOT_FILES = ("armar3", "armar6", "dual_panda")


def _typo(key: str) -> str:
    """``key`` with its two middle letters swapped (a different word of the same letters)."""
    i = max(1, len(key) // 2 - 1)
    swapped = key[:i] + key[i + 1] + key[i] + key[i + 2 :]
    return swapped if swapped != key else key + "s"


def _robot_text(name: str) -> str:
    text = (robots_dir() / f"{name}.toml").read_text()
    return re.sub(r'^model = "(.*)"', lambda m: f'model = "{robots_dir() / m.group(1)}"', text, flags=re.M)


def _robot_keys(name: str) -> list[tuple[str, str]]:
    """(table, key) of every fixed key the bundled robot file uses: top level and fixed tables."""
    desc = tomllib.loads(_robot_text(name))
    keys = [("", k) for k in desc]
    for where in TABLE_KEYS:
        table = desc
        for part in where.split("."):
            table = table.get(part, {})
        keys += [(where, k) for k in table]
    return keys


CASES = [(name, where, key) for name in ROBOT_FILES for where, key in _robot_keys(name)]


@pytest.mark.parametrize(("name", "where", "key"), CASES, ids=[f"{n}:{w or 'top'}.{k}" for n, w, k in CASES])
def test_every_robot_key_misspelt_is_refused_naming_the_key(tmp_path, name, where, key):
    text = _robot_text(name)
    table = f"{where}.{key}" if where else key
    if re.search(rf"^\[{re.escape(table)}[\].]", text, re.M):  # a table: rename its header(s)
        new = f"{where}.{_typo(key)}" if where else _typo(key)
        text = re.sub(rf"^\[{re.escape(table)}([\].])", lambda m: f"[{new}" + m.group(1), text, flags=re.M)
    else:  # a key = value line, after its table's header
        start = text.index(f"[{where}]\n") if where else 0
        m = re.compile(rf"^{re.escape(key)}(\s*=)", re.M).search(text, start)
        assert m is not None
        text = text[: m.start()] + _typo(key) + text[m.start() + len(key) :]
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    with pytest.raises(RobotError) as e:
        load_robot(str(path))
    message = str(e.value)
    assert "\n" not in message and message.startswith(str(path))
    assert f"unknown key {_typo(key)!r}" in message
    assert f"did you mean {key!r}" in message
    assert (f"[{where}]" if where else "top-level") in message


def test_the_keys_the_loader_knows_are_the_ones_the_bundled_files_use():
    """KEYS is not a list of guesses: every bundled robot file's keys are in it, and every key in
    it is read by the loader (or documented in robots/README.md)."""
    used = {k for name in ROBOT_FILES for w, k in _robot_keys(name) if not w}
    assert used <= set(KEYS)
    documented = (robots_dir() / "README.md").read_text()
    assert all(k in documented or k == "mjcf" for k in KEYS)


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (
            lambda t: t.replace('mmm = "LEx_joint"', 'mmm = "LEx_jiont"', 1),
            "'LEx_jiont' is not a joint of the MMM model",
        ),
        (
            lambda t: t.replace('site = "hand_mount"', 'site = "hand_mout"'),
            r"\[manipulability\] site 'hand_mout'",
        ),
        (
            lambda t: t.replace('unlimited_joints = ["ArmL2_Sho1", ', "unlimited_joints = ["),
            "leaves out ArmL2_Sho1",
        ),
        (
            lambda t: t.replace('unlimited_joints = ["', 'unlimited_joints = ["ArmL1_Cla1", "'),
            "lists ArmL1_Cla1",
        ),
    ],
)
def test_robot_file_names_are_checked_against_the_models(tmp_path, edit, message):
    """An MMM joint, the manipulability site and the unlimited joints are checked against the MMM
    model and the robot's model, and blamed on the robot file (not on a motion or the MJCF)."""
    text = _robot_text("armar6")
    changed = edit(text)
    assert changed != text
    path = tmp_path / "armar6.toml"
    path.write_text(changed)
    with pytest.raises(RobotError, match=message) as e:
        load_robot(str(path))
    assert str(e.value).startswith(str(path))


def test_a_keypoint_description_typo_is_refused(tmp_path):
    from hlik.human.load import load_motion

    (tmp_path / "k.csv").write_text("0,0,0\n")
    path = tmp_path / "k.toml"
    path.write_text('data = "k.csv"\nrat = 30\n[keypoints]\nleft_wrist = 0\n')
    with pytest.raises(
        HlikError, match=r"unknown key 'rat' in the top-level table \(did you mean 'rate'\?\)"
    ):
        load_motion(path)


def test_a_metric_file_typo_is_refused(tmp_path):
    from hlik.criteria.unified import Metric, load_metric

    path = tmp_path / "m.toml"
    path.write_text(Metric.table3().to_toml().replace("[weights]", "[wieghts]"))
    with pytest.raises(HlikError, match=r"unknown key 'wieghts'.*did you mean 'weights'"):
        load_metric(path)


@pytest.mark.parametrize(
    ("table", "typo", "meant"),
    [("correlation", "exclud", "solvers"), ("correlation", "single_criterion", "single_criteria"),
     ("evaluation", "pair", "pairs"), ("stacks", "poses", "pose")],
)  # fmt: skip
def test_an_approach_file_typo_is_refused_in_every_table(tmp_path, table, typo, meant):
    from hlik.study.approaches import load_approaches

    path = tmp_path / "a.toml"
    extra = "" if table == "correlation" else f"[{table}]\n"
    path.write_text(f'[correlation]\nsolvers = ["jm"]\n{extra}{typo} = []\n')
    with pytest.raises(HlikError, match=rf"unknown key '{typo}' in \[{table}\]") as e:
        load_approaches(path)
    if typo != "exclud":
        assert f"did you mean {meant!r}" in str(e.value)


def test_a_pair_given_in_both_orders_is_one_approach(tmp_path):
    from hlik.study.approaches import load_approaches

    path = tmp_path / "a.toml"
    path.write_text(
        '[correlation]\nsolvers = ["jm"]\n[evaluation]\nsolvers = ["qp"]\n'
        'pairs = [["SYN", "HJA_r"], ["HJA_r", "SYN"]]\n'
    )
    names = [a.name for a in load_approaches(path) if not a.correlation]
    assert names.count("qp+SYN+HJA_r") == 1 and "qp+HJA_r+SYN" not in names
