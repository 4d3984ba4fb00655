"""`hlik study`: the approach file, the analysis against hand-computed values, a tiny study end to
end (Parquet schema, resume, failures) and the derived metric's round trip through the CLI."""

from __future__ import annotations

import json
import os
from dataclasses import replace
from pathlib import Path
from types import MappingProxyType

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from typer.testing import CliRunner

from hlik.cli import app
from hlik.criteria import registry
from hlik.criteria.unified import Metric, load_metric
from hlik.robot.model import SIDES, load_robot
from hlik.study.analysis import Correlation, Ranking, hierarchy_weights, spearman, ward
from hlik.study.approaches import Approach, load_approaches
from hlik.study.report import findings
from hlik.study.runner import plan, run_cells, run_study
from hlik.util.errors import HlikError
from hlik.util.paths import demo_motion_path

NAMES = registry.human_likeness()


def _linkage(merges):
    """SciPy linkage from (a, b, height) merges, with the member counts filled in."""
    n = len(merges) + 1
    size = {i: 1 for i in range(n)}
    z = []
    for k, (a, b, h) in enumerate(merges):
        size[n + k] = size[a] + size[b]
        z.append([a, b, h, size[n + k]])
    return np.array(z, dtype=float)


def test_the_papers_dendrogram_gives_table_iii():
    """formulas.md §10: five top-level groups (merges within 0.15 of each other above the cut-off)
    give 1/5, 1/20, 1/15 and 1/30, Table III's weights."""
    i = {n: k for k, n in enumerate(NAMES)}
    z = _linkage(
        [
            (i["HJA_r"], i["SYN_r"], 0.2),  # 11, below the cut-off: one cluster
            (i["EEA"], i["SOA_x"], 0.3),  # 12
            (12, i["SOA_q"], 0.4),  # 13
            (13, i["EEA_r"], 0.5),  # 14: {EEA, SOA_x, SOA_q, EEA_r}
            (i["SYN"], 11, 0.8),  # 15
            (i["HJL"], 15, 0.85),  # 16: within 0.15 of 15 -> HJL, SYN, {HJA_r, SYN_r}
            (14, 16, 1.05),  # 17: 0.2 above 16, so 16 stays one child
            (i["MIS"], 17, 1.1),  # 18
            (i["MJE"], 18, 1.15),  # 19
            (i["MAN_r"], 19, 1.2),  # root: MAN_r, MJE, MIS, 14, 16
        ]
    )
    weights = hierarchy_weights(z, NAMES)
    assert weights == pytest.approx(dict(Metric.table3().weights))
    assert sum(weights.values()) == pytest.approx(1.0)


def test_weights_split_a_cluster_below_the_cut_off_equally_and_sum_to_one():
    z = _linkage([(0, 1, 0.1), (2, 11, 0.2)] + [(k, 12 + k - 3, 1.0 + 0.3 * k) for k in range(3, 11)])
    weights = hierarchy_weights(z, NAMES)
    assert weights[NAMES[0]] == weights[NAMES[1]] == weights[NAMES[2]]
    assert sum(weights.values()) == pytest.approx(1.0)


def test_spearman_matches_the_rank_formula():
    """No ties: rho = 1 - 6 sum d^2 / (n (n^2 - 1)); x and y differ by swapped neighbours."""
    x, y = np.array([1.0, 2, 3, 4, 5]), np.array([2.0, 1, 4, 3, 5])
    table = pa.table({"h_a": x, "h_b": y, "h_c": np.full(5, 0.3)})
    c = spearman(table, ("a", "b", "c"))
    assert c[0, 1] == pytest.approx(1 - 6 * 4 / (5 * 24))  # 0.8
    assert c[0, 2] == 0.0 and c[2, 2] == 1.0  # a constant column: uncorrelated, not NaN


def test_ward_merges_by_the_lance_williams_update():
    """d(a, b) = 0.2, d(a, c) = d(b, c) = 1: {a, b} at 0.2, then c at sqrt((2 + 2 - 0.04) / 3)."""
    c = 1.0 - np.array([[0, 0.2, 1.0], [0.2, 0, 1.0], [1.0, 1.0, 0]])
    z = ward(c)
    assert z[:, 2] == pytest.approx([0.2, np.sqrt(3.96 / 3)])
    assert sorted(z[0, :2]) == [0, 1] and sorted(z[1, :2]) == [2, 3]  # {a, b} first, then c


def test_the_papers_approach_file():
    approaches = load_approaches()
    names = [a.name for a in approaches]
    assert len(names) == len(set(names))
    corr = [a for a in approaches if a.correlation]
    assert {a.solver for a in corr} == {"jm", "jv", "slsqp", "qp"}
    assert all(len(a.criteria) <= 1 for a in corr) and len(corr) == 1 + 3 * (1 + len(NAMES)) - 1
    assert {"slsqp+SYN+HJA_r", "qp+SYN+SYN_r", "jv+HJA_r+SOA_q", "slsqp (relative)"} <= set(names)
    assert all(a.stack == "paper_opt" for a in approaches if a.scenario == "pose")
    # the paper leaves MJE out of JV (Sec. IV-A) and JV out of the relative pose (Sec. V-B)
    assert "jv+MJE" not in names and not any(
        a.solver == "jv" and a.scenario == "relative" for a in approaches
    )
    assert {"slsqp+MJE", "qp+MJE", "qp (relative)"} <= set(names)


def test_the_quick_approach_file_is_bundled_by_name():
    quick = load_approaches("quick")
    assert {a.solver for a in quick} == {"jm", "qp"} and len(quick) == 1 + 1 + len(NAMES) + 3
    with pytest.raises(HlikError, match="bundled: paper, quick"):
        load_approaches("slow")


@pytest.mark.parametrize(
    "text, problem",
    [
        ("[correlation]\nsolvers = ['jm', 'ik']", "unknown solver 'ik'"),
        ("[evaluation]\nsolvers = ['qp']\npairs = [['SYN', 'XYZ']]", "unknown criterion 'XYZ'"),
        ("[evaluation]\nsolvers = ['qp']\nscenarios = ['side']", "unknown scenario 'side'"),
        ("[extra]\na = 1", "unknown key 'extra' in the top level"),
        (
            "[corelation]\nsolvers = ['jm']",
            "unknown key 'corelation' in the top level (did you mean 'correlation'?)",
        ),
        ("[correlation]\nsolvers = 'jm'", "solvers must be a list"),
        ("[correlation]\nsolvers = ['jm']\nsingle_criteria = 'yes'", "true or false"),
        ("", "no approach for the correlation"),
        ("exclude = 'jv'\n[correlation]\nsolvers = ['jm']", "exclude must be a list"),
        ("exclude = ['jv+XYZ']\n[correlation]\nsolvers = ['jm', 'jv']", "'jv+XYZ' matches no approach"),
    ],
)
def test_bad_approach_files_name_the_file_and_the_problem(tmp_path, text, problem):
    path = tmp_path / "mine.toml"
    path.write_text(text)
    with pytest.raises(HlikError, match="mine.toml") as err:
        load_approaches(path)
    assert problem in str(err.value)


TINY = (Approach("jm", correlation=True), Approach("qp", correlation=True), Approach("qp", ("SYN", "HJA_r")))


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    out = tmp_path_factory.mktemp("study")
    result = run_study([demo_motion_path()], ["dual_panda"], TINY, out, seconds=1.0, workers=1)
    return out, result


def test_a_tiny_study_writes_cells_metric_and_report(tiny):
    out, result = tiny
    cells = sorted((out / "cells").glob("*.parquet"))
    assert len(cells) == 3 and not any(o.error for o in result.outcomes)
    table = pq.read_table(cells[0])
    expected = {f"h_{n}" for n in (*NAMES, *registry.functional())}
    expected |= {"take", "robot", "approach", "frame", "time", "fpos_left", "fpos_right", "iterations"}
    expected |= {"converged", "failed", "solve_time", "collision", "speed_ratio", "scenario", "solver"}
    for who in ("robot", "subject"):
        expected |= {f"lean_{who}"}
        expected |= {
            f"{m}_{side}_{who}"
            for m in ("elbow_front", "hand_front", "wrist_front", "swivel")
            for side in SIDES
        }
    assert set(table.schema.names) == expected
    assert np.all(np.isfinite(table.column("lean_robot").to_numpy()))
    assert table.num_rows == 101 and np.all(np.isfinite(table.column("h_SYN").to_numpy()))
    assert sum(result.metric.weights.values()) == pytest.approx(1.0)
    assert all(v > 0 for v in result.metric.x0.values())
    assert {p.name for p in out.glob("*.png")} == {"correlation.png", "dendrogram.png", "scores_pose.png"}
    html = (out / "report.html").read_text()
    assert "Table III" in html and "qp+SYN+HJA_r" in html and html.count("data:image/png;base64") == 3
    # one robot, one 1 s take: no deviation across robots or takes, and no finding judged
    assert "across robots none with 1 robot" in html and "across motions none with 1 take" in html
    assert (
        "<td>yes</td>" not in html
        and "<td>no</td>" not in html
        and "not judged: 1 take (needs 3), 202 frames (needs 1000)" in html  # two approaches correlated
    )
    rows = result.rankings[0].rows
    assert [r["m_hl_f"] for r in rows] == sorted((r["m_hl_f"] for r in rows), reverse=True)
    for r in rows:  # Eq. 2 with the derived weights, m_f of the pose scenario
        assert r["m_hl"] == pytest.approx(sum(result.metric.weights[k] * r["m"][k] for k in NAMES))
        assert r["m_f"] == pytest.approx(np.mean([r["m"][k] for k in ("fJLA", "fPOS", "fORI")]))


def test_a_rerun_reuses_every_cell_and_redoes_only_a_lost_one(tiny):
    out, _ = tiny
    cells = sorted((out / "cells").glob("*.parquet"))
    before = {p: p.stat().st_mtime_ns for p in cells}
    cells[1].unlink()
    (out / "cells" / f".{cells[1].name}.abc.tmp").write_bytes(b"half a cell")  # a killed write
    result = run_study([demo_motion_path()], ["dual_panda"], TINY, out, seconds=1.0, workers=1)
    assert sum(not o.reused for o in result.outcomes) == 1
    assert cells[1].exists() and all(p.stat().st_mtime_ns == before[p] for p in cells if p != cells[1])


def test_cells_of_other_lengths_or_rates_are_not_reused():
    names = {c.file_name for s in (1.0, 2.0, None) for c in plan([demo_motion_path()], ["armar6"], TINY, s)}
    assert len(names) == 3 * len(TINY)


def test_a_take_and_robot_are_placed_once_for_all_their_approaches(tmp_path, monkeypatch):
    from hlik.study import runner
    from hlik.study.dataset import run_cell

    calls = []
    real = runner.placement_from_spec
    monkeypatch.setattr(runner, "placement_from_spec", lambda *a: calls.append(a[0]) or real(*a))
    runner._scene.cache_clear()
    cells = plan([demo_motion_path()], ["armar6"], TINY, 0.2)
    outcomes = run_cells(cells, tmp_path, workers=1)
    assert not any(o.error for o in outcomes) and calls == [load_robot("armar6").placement]
    # the shared placement is the one each cell would have found alone
    robot, learned = runner._robot("armar6")
    alone = run_cell(cells[1], robot, learned)
    assert alone.column("h_fPOS").equals(pq.read_table(tmp_path / cells[1].file_name).column("h_fPOS"))


def test_a_failing_cell_is_listed_not_fatal(tmp_path):
    bad = tmp_path / "broken.xml"
    bad.write_text("<MMM><Motion name='x'>")
    outcomes = run_cells(plan([bad], ["dual_panda"], TINY[:1], 1.0), tmp_path / "cells", workers=1)
    assert outcomes[0].error and "broken.xml" in outcomes[0].error and outcomes[0].path is None
    assert not list((tmp_path / "cells").glob("*"))


def test_a_metric_from_part_of_the_cells_says_so(tmp_path):
    """With a take that fails, the metric comes from the others: its source says it is partial
    (where the metric is kept, not only in the run's output)."""
    bad = tmp_path / "broken.xml"
    bad.write_text("<MMM><Motion name='x'>")
    result = run_study(
        [demo_motion_path(), bad], ["dual_panda"], TINY[:2], tmp_path / "out", seconds=1.0, workers=1
    )
    assert sum(o.error is not None for o in result.outcomes) == 2
    assert "partial: 2 of 4 cells failed" in load_metric(result.metric_file).source


def test_the_derived_metric_round_trips_through_hlik_evaluate(tiny, tmp_path):
    out, result = tiny
    assert load_metric(out / "metric.toml") == result.metric
    npz = tmp_path / "demo.rrd"
    runner = CliRunner()
    run = runner.invoke(
        app, ["run", "--robot", "dual_panda", "--out", str(npz), "--metric", str(out / "metric.toml")]
    )
    assert run.exit_code == 0, run.output
    ev = runner.invoke(
        app, ["evaluate", str(npz.with_suffix(".npz")), "--json", "--metric", str(out / "metric.toml")]
    )
    assert ev.exit_code == 0, ev.output
    data = json.loads(ev.stdout)
    m = {k: v["m"] for k, v in data["metrics"].items()}
    assert data["m_hl"] == pytest.approx(sum(result.metric.weights[k] * m[k] for k in NAMES))
    assert data["metric"] == result.metric.source


@pytest.mark.parametrize(
    "text, problem",
    [
        ("[weights]\nEEA = 1.0\n[x0]\nEEA = 0.3", "[weights] missing"),
        ("[weights]\nSYNN = 1.0\n[x0]\nEEA = 0.3", "unknown key 'SYNN' in [weights] (did you mean 'SYN'?)"),
        ("[xo]\nSYN = 1.0", "unknown key 'xo' in the top-level table (did you mean 'x0'?)"),
        (
            "\n".join(["[weights]", *(f"{n} = 0.5" for n in NAMES), "[x0]", *(f"{n} = 1.0" for n in NAMES)]),
            "sum to 1",
        ),
    ],
)
def test_bad_metric_files_name_the_file_and_the_problem(tmp_path, text, problem):
    path = tmp_path / "m.toml"
    path.write_text(text)
    with pytest.raises(HlikError, match="m.toml") as err:
        load_metric(path)
    assert problem in str(err.value)
    # on the command line the message prints as written ("[weights]" is not rich markup); the
    # metric is read before the trajectory (which is only checked to be there)
    path.with_suffix(".npz").write_bytes(b"not read")
    result = CliRunner().invoke(app, ["evaluate", str(path.with_suffix(".npz")), "--metric", str(path)])
    assert result.exit_code == 2 and problem in result.stderr  # "[weights]" included where named


def test_ray_gives_the_in_process_result(tiny, tmp_path):
    pytest.importorskip("ray")
    out, _ = tiny
    result = run_study([demo_motion_path()], ["dual_panda"], TINY, tmp_path, seconds=1.0, workers=2)
    for path in sorted((out / "cells").glob("*.parquet")):
        a, b = pq.read_table(path), pq.read_table(tmp_path / "cells" / path.name)
        for name in a.schema.names:
            if name != "solve_time":
                assert a.column(name).equals(b.column(name)), name
    assert not any(o.error for o in result.outcomes)


def test_cells_without_the_posture_columns_still_read_with_new_ones(tiny, tmp_path):
    """A cell an older hlik wrote (no posture columns) is read beside new ones, nulls in its rows."""
    from hlik.study.dataset import read_dataset

    out, _ = tiny
    new = sorted((out / "cells").glob("*.parquet"))[0]
    table = pq.read_table(new)
    old = tmp_path / "old.parquet"
    pq.write_table(table.drop_columns([c for c in table.schema.names if c.startswith("lean_")]), old)
    both = read_dataset([new, old])
    assert both.num_rows == 2 * table.num_rows
    assert both.column("lean_robot").null_count == table.num_rows


def test_findings_are_judged_only_on_enough_data():
    names = registry.human_likeness()
    rng = np.random.default_rng(0)
    mean = np.corrcoef(rng.normal(size=(len(names), 50)))
    rows = (
        {"approach": "slsqp+SYN", "m_hl_f": 0.7, "cells": 24},
        {"approach": "jv", "m_hl_f": 0.6, "cells": 2},
    )
    ranking = Ranking("pose", rows)
    for takes, frames, judged in ((2, 5000, False), (8, 999, False), (8, 1000, True)):
        corr = Correlation(names, MappingProxyType({}), mean, 0.1, 0.1, takes=takes, frames=frames)
        verdicts = [v for f, v, _ in findings(corr, [ranking]) if "OPT" not in f]
        assert all((v in ("yes", "no")) == judged for v in verdicts), (takes, frames, verdicts)
    opt = [v for f, v, _ in findings(corr, [ranking]) if "OPT" in f]
    assert opt == ["not judged: 2 cells per approach; needs 3"]
    enough = Ranking("pose", tuple({**r, "cells": 3} for r in rows))
    assert [v for f, v, _ in findings(corr, [enough]) if "OPT" in f] == ["yes"]
    quick = Ranking("pose", ({"approach": "jm", "m_hl_f": 0.6, "cells": 8}, rows[1]))  # no slsqp
    assert [v for f, v, _ in findings(corr, [quick]) if "OPT" in f] == [
        "not judged: the study ran no slsqp approach"
    ]
    one = Correlation(
        names, MappingProxyType({"armar6": mean}), mean, float("nan"), 0.05, takes=4, frames=2000
    )
    assert (
        "across robots none with 1 robot" in one.deviation_text()
        and "0.050 over 4 takes (paper 0.1)" in one.deviation_text()
    )
    two = replace(one, takes=2)  # a deviation over two takes is shown, and said to be too few
    assert "0.050 over 2 takes (paper 0.1; too few takes to compare, needs 3)" in two.deviation_text()


# --- Ray: a study that stops cleanly, joins a cluster, falls back (issue 30) ----------------------


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _ray_processes() -> set[int]:
    """PIDs of Ray's processes on this machine (their names, as ``ps`` shows them)."""
    import subprocess

    ps = subprocess.run(["ps", "-eo", "pid=,args="], capture_output=True, text=True).stdout
    marks = ("ray::", "raylet", "gcs_server", "ray/dashboard", "log_monitor.py")
    return {int(line.split()[0]) for line in ps.splitlines() if any(m in line for m in marks)}


def test_a_local_ray_that_does_not_start_falls_back_in_one_line(tmp_path, monkeypatch):
    ray = pytest.importorskip("ray")

    def fail(*args, **kwargs):
        raise RuntimeError("The current node timed out during startup.\nThis could happen because ...")

    monkeypatch.setattr(ray, "init", fail)
    notes: list[str] = []
    cells = plan([demo_motion_path()], ["dual_panda"], TINY[:1], 0.3)
    outcomes = run_cells(cells, tmp_path, workers=2, notes=notes)
    assert not any(o.error for o in outcomes) and len(outcomes) == 1
    why = "The current node timed out during startup. This could happen because ..."
    assert notes == [f"Ray did not start ({why}): the cells run in this process"]


@pytest.mark.parametrize(("signum", "code"), [("TERM", 143), ("INT", 130), ("KILL", -9)])
def test_a_ray_study_stopped_by_a_signal_leaves_no_ray_process(tmp_path, signum, code):
    """SIGTERM ends the study as Ctrl-C does (not Ray's C++ dump, exit -6), and after any of the
    three no process of its local Ray is left (SIGKILL: study/reaper.py ends them)."""
    import time

    pytest.importorskip("ray")
    before = _ray_processes()
    _, err, returncode = _stopped_study(tmp_path / "s", signum, seconds=4, workers=2)  # Ray up first
    assert returncode == code, err
    assert "SIGTERM received" not in err and "Traceback" not in err, err
    time.sleep(5)  # the reaper's SIGTERM, then SIGKILL after 2 s
    assert _ray_processes() <= before


def test_a_study_joins_a_ray_cluster_with_token_authentication(tmp_path):
    """A head node started the usual way (``ray start --head``; Ray >= 2.59 turns token
    authentication on for it) is joined through ``--address`` without setting anything."""
    import subprocess
    import sys

    pytest.importorskip("ray")
    ray_cli = Path(sys.executable).with_name("ray")
    port = _free_port()
    env = {k: v for k, v in os.environ.items() if not k.startswith("RAY_")}
    head = [str(ray_cli), "start", "--head", f"--port={port}", "--num-cpus=2", "--include-dashboard=false"]
    subprocess.run(head, env=env, check=True, capture_output=True, timeout=120)
    try:
        args = [sys.executable, "-m", "hlik", "study", str(demo_motion_path()), "--robots", "dual_panda"]
        args += ["--approaches", "quick", "--seconds", "0.5", "--address", f"127.0.0.1:{port}"]
        args += ["--out", str(tmp_path / "s")]
        done = subprocess.run(
            args, env={**env, "HLIK_CORPUS": "demo"}, capture_output=True, text=True, timeout=300
        )
        assert done.returncode == 0, done.stderr[-2000:]
        assert (
            "gcs_client" not in done.stderr and len(list((tmp_path / "s" / "cells").glob("*.parquet"))) == 16
        )
    finally:
        subprocess.run([str(ray_cli), "stop", "--force"], env=env, capture_output=True, timeout=120)


@pytest.mark.parametrize(
    ("signum", "code", "how"), [("TERM", 143, "terminated"), ("INT", 130, "interrupted")]
)
def test_a_study_stopped_by_a_signal_says_what_it_kept_and_resumes(tmp_path, signum, code, how):
    """In-process cells (no Ray): SIGTERM ended the study silently and Ctrl-C said "nothing
    written" over the cells it had kept; now one line counts them, and the same command reuses them."""
    _, err, returncode = _stopped_study(tmp_path / "s", signum, seconds=0.5, workers=1)
    kept = len(list((tmp_path / "s" / "cells").glob("*.parquet")))
    assert returncode == code, err
    assert err.strip().splitlines()[-1].startswith(f"error: {how}: {kept} of ") and "resume" in err, err
    assert "nothing written" not in err and "Traceback" not in err and kept >= 1
    if signum == "INT":
        return  # the resume is the same after either
    # the cells of the same command, run again (without the report): the kept ones are reused
    cells = plan([demo_motion_path()], ["dual_panda"], load_approaches("quick"), 0.5)
    outcomes = run_cells(cells, tmp_path / "s" / "cells", workers=1)
    assert sum(o.reused for o in outcomes) == kept and not any(o.error for o in outcomes)


def _stopped_study(out: Path, signum: str, seconds: float, workers: int) -> tuple[str, str, int]:
    """``hlik study`` of the demo (2-Panda, the quick approaches) in a subprocess, sent SIG<signum>
    once its first cell is written: its stdout, stderr and exit code."""
    import signal as signals
    import subprocess
    import sys
    import time

    args = [sys.executable, "-m", "hlik", "study", str(demo_motion_path()), "--robots", "dual_panda"]
    args += ["--approaches", "quick", "--seconds", str(seconds), "--workers", str(workers), "--out", str(out)]
    env = {**os.environ, "HLIK_CORPUS": "demo"}
    study = subprocess.Popen(args, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while not list((out / "cells").glob("*.parquet")) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert study.poll() is None, study.communicate()
    study.send_signal(getattr(signals, f"SIG{signum}"))
    stdout, stderr = study.communicate(timeout=60)
    return stdout, stderr, study.returncode
