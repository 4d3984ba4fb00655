"""``hlik learn``: fit (or show) the learned criteria of a robot."""

from __future__ import annotations

from typing import Annotated

import typer
from rich.table import Table

from hlik.cli.app import (
    DEMO_CORPUS_WARNING,
    CorpusOpt,
    console,
    counting,
    one_line,
    print_table,
    resolve_corpus,
    warn,
)


def learn(
    robots: Annotated[list[str] | None, typer.Argument(help="Robot names (default: all).")] = None,
    corpus: CorpusOpt = None,
) -> None:
    """Fit (or load from the cache) synergies, the swivel regressor and lambda_R; print what was
    learned. A --corpus folder is remembered as the default of later commands
    (~/.config/hlik/config.toml; $HLIK_CORPUS and ./hlik.toml come first)."""
    import numpy as np

    from hlik.criteria.learned import learn as learn_robot
    from hlik.robot.files import available_robots
    from hlik.robot.model import load_robot
    from hlik.util.paths import cache_dir, remember_corpus

    paper = {"armar3": 7.25, "armar6": 8.76, "dual_panda": 4.7}
    table = Table("robot", "corpus", "PCA var. (5)", "1st-order var. (5)", "Psi rms", "lambda_R", "paper")
    with one_line():
        given = corpus
        corpus, source = resolve_corpus(corpus)
        for name in robots or available_robots():
            r = load_robot(name)
            with counting(f"learning {name}'s criteria from the corpus") as progress:
                lrn = learn_robot(r, corpus, progress=progress)
            warn(lrn.notes)
            table.add_row(
                r.name,
                f"{len(lrn.corpus)} files",
                f"{100 * lrn.synergies.explained.sum():.1f} %",
                f"{100 * lrn.synergies.vel_explained.sum():.1f} %",
                f"{np.degrees(lrn.swivel_rms):.1f}°",
                f"{lrn.scale:.2f}",
                f"{paper.get(r.name, float('nan')):g}",
            )
        folder = cache_dir()
        remembered = remember_corpus(corpus) if given is not None and corpus is not None else None
    print_table(table)
    console.print(f"cache: {folder}", soft_wrap=True)
    if remembered is not None:
        console.print(
            f"corpus {corpus} remembered in {remembered}: the default of later commands", soft_wrap=True
        )
    elif corpus is None and not source:
        warn([DEMO_CORPUS_WARNING])
    else:
        console.print(f"corpus {corpus} ({source})", soft_wrap=True)
