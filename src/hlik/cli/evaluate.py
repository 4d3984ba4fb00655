"""``hlik evaluate``: the scores of a trajectory file."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from hlik.cli.app import (
    DEMO_CORPUS_WARNING,
    FLAG,
    CorpusOpt,
    MetricOpt,
    check_trajectory_file,
    console,
    one_line,
    print_table,
    resolve_corpus,
    trajectory_and_robot,
    warn,
)
from hlik.cli.run import _corpus_label

EvaluateScenarioOpt = Annotated[
    str | None,
    typer.Option(
        help="Functional score: pose (hand poses) or relative (relative pose of the hands); default: "
        "the one the run was made for (its stack's), pose for a file that does not say."
    ),
]


def evaluate(
    trajectory: Annotated[Path, typer.Argument(help="Trajectory .npz written by `hlik run`.")],
    json_out: Annotated[
        bool, typer.Option("--json", help="Print one JSON object.", metavar=FLAG, show_default=False)
    ] = False,
    corpus: CorpusOpt = None,
    scenario: EvaluateScenarioOpt = None,
    metric: MetricOpt = None,
) -> None:
    """Human-likeness criteria h_i and scores m_i, m_hl, m_f and m_hl,f of a trajectory."""
    import json

    with one_line():
        check_trajectory_file(trajectory)
        from hlik.criteria.learned import learn
        from hlik.criteria.unified import check_scenario, load_metric, midpoints
        from hlik.metrics import evaluate as evaluate_trajectory

        if scenario is not None:
            check_scenario(scenario)
        unified_metric = load_metric(metric) if metric is not None else None
        traj, r = trajectory_and_robot(trajectory)
        scenario = scenario or traj.scenario or "pose"
        folder, source = resolve_corpus(corpus)
        learned = learn(r, folder)
        ev = evaluate_trajectory(traj, r, learned, scenario=scenario, metric=unified_metric)
    warn([*learned.notes, *([DEMO_CORPUS_WARNING] if folder is None and not source else [])])
    corpus_label = _corpus_label(folder, learned.corpus, source)
    if json_out:  # the recording's panel holds ev.to_json(); the corpus is the command's own
        sys.stdout.write(json.dumps({**ev.to_json(), "corpus": corpus_label}, indent=2) + "\n")
        return
    x0 = midpoints(scenario, ev.metric)
    title = f"{trajectory.name}: {Path(traj.robot).stem}, {traj.solver}; weights and x0: {ev.metric.source}"
    table = Table("criterion", "mean h", "x0", "m", title=title)
    for k in x0:
        table.add_row(k, f"{ev.h[k].mean():.4g}", f"{x0[k]:g}", f"{ev.m[k]:.3f}")
    print_table(table)
    console.print(f"m_hl = {ev.m_hl:.3f}   m_f ({scenario}) = {ev.m_f:.3f}   m_hl,f = {ev.m_hl_f:.3f}")
    console.print(f"criteria learned from: {corpus_label}", soft_wrap=True)
