"""The study's report: figures (PNG, matplotlib) and one self-contained HTML file.

Fig. 4: the mean Spearman matrix in dendrogram order; Fig. 5: Ward's dendrogram with the cut-off;
Fig. 6: per-criterion scores m_i of the best approaches; tables of the derived weights and x0 next
to Table III, the rankings, the paper's qualitative findings (reproduced or not) and failed cells.
"""

from __future__ import annotations

import base64
import html
from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only, no display
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from scipy.cluster import hierarchy  # noqa: E402

from hlik.criteria import unified  # noqa: E402
from hlik.study.analysis import CUTOFF, Correlation, Ranking, ward  # noqa: E402
from hlik.util.atomic import atomic_path  # noqa: E402
from hlik.util.version import __version__  # noqa: E402

WEAK = 0.3  # |rho| below which a criterion counts as weakly correlated with another
STYLE = (
    "<style>body{font-family:sans-serif;max-width:1100px;margin:auto}"
    "table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #ccc;padding:2px 6px;"
    "text-align:right}th{background:#eee}img{max-width:100%}</style>"
)


def _save(fig, path: Path) -> Path:
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=120, bbox_inches="tight", format="png")
    plt.close(fig)
    return path


def heatmap(corr: Correlation, path: Path) -> Path:
    """Fig. 4: the mean Spearman matrix, rows and columns in the dendrogram's leaf order."""
    order = hierarchy.leaves_list(ward(corr.mean))
    names = [corr.names[i] for i in order]
    c = corr.mean[np.ix_(order, order)]
    fig, ax = plt.subplots(figsize=(6.5, 5.5))
    im = ax.imshow(c, cmap="RdBu_r", vmin=-1, vmax=1)
    ax.set_xticks(range(len(names)), names, rotation=60, ha="right")
    ax.set_yticks(range(len(names)), names)
    for i in range(len(names)):
        for j in range(len(names)):
            ax.text(j, i, f"{c[i, j]:.2f}", ha="center", va="center", fontsize=6.5)
    fig.colorbar(im, ax=ax, label="Spearman ρ (mean over robots)")
    # over the figure, not the axes: centred on the matrix it ran into the colour bar
    fig.suptitle("Correlation of the human-likeness criteria (cf. paper Fig. 4)")
    return _save(fig, path)


def dendrogram(corr: Correlation, path: Path) -> Path:
    """Fig. 5: Ward's dendrogram of D = 1 - C with the cut-off."""
    fig, ax = plt.subplots(figsize=(7, 4))
    hierarchy.dendrogram(
        ward(corr.mean), labels=list(corr.names), ax=ax, color_threshold=CUTOFF, leaf_rotation=45
    )
    # in a legend, which matplotlib places clear of the branches (a label on the line crossed one)
    ax.axhline(CUTOFF, color="k", linestyle="--", linewidth=1, label=f"cut-off {CUTOFF}")
    ax.legend(loc="best", fontsize=8)
    ax.set_ylabel("Ward distance on 1 − ρ")
    ax.set_title("Hierarchy of the criteria (cf. paper Fig. 5)")
    return _save(fig, path)


def score_bars(ranking: Ranking, path: Path, best: int = 4) -> Path:
    """Fig. 6: m_i per criterion, m_hl and m_f of the ``best`` approaches (and JM, if ranked)."""
    rows = list(ranking.rows[:best]) + [r for r in ranking.rows[best:] if r["approach"].startswith("jm")]
    keys = list(rows[0]["m"]) if rows else []
    fig, ax = plt.subplots(figsize=(10, 3.8))
    width = 0.8 / max(len(rows), 1)
    labels = keys + ["m_hl", "m_f"]
    for i, r in enumerate(rows):
        values = [r["m"][k] for k in keys] + [r["m_hl"], r["m_f"]]
        ax.bar(
            np.arange(len(labels)) + i * width, values, width, label=f"{r['approach']} ({r['m_hl_f']:.3f})"
        )
    ax.set_xticks(np.arange(len(labels)) + 0.4 - width / 2, labels, rotation=60, ha="right")
    ax.set_ylim(0, 1)
    ax.set_ylabel("score")
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.0, 1.0))
    jm = " and JM" if any(r["approach"].startswith("jm") for r in rows[best:]) else ""
    ax.set_title(
        f"The {best} best approaches{jm} by m_hl,f (in brackets), {ranking.scenario} scenario (cf. Fig. 6)"
    )
    return _save(fig, path)


# The least data a finding is judged on: a correlation over fewer takes or frames, or a ranking
# over fewer cells per approach, says more about the takes than about the criteria.
MIN_TAKES = 3
MIN_FRAMES = 1000
MIN_CELLS = 3


def findings(corr: Correlation, rankings: Sequence[Ranking]) -> list[tuple[str, str, str]]:
    """The paper's qualitative findings: each with its verdict (``yes``, ``no``, or ``not judged:``
    and why, where the study is too small: fewer than :data:`MIN_TAKES` takes or
    :data:`MIN_FRAMES` frames, or :data:`MIN_CELLS` cells per approach) and the numbers."""
    c, idx = corr.mean, {n: i for i, n in enumerate(corr.names)}
    out = []
    short = corr.takes < MIN_TAKES or corr.frames < MIN_FRAMES
    data = f"{corr.takes} take{'s' * (corr.takes != 1)}, {corr.frames} frames"

    def verdict(ok: bool, small: bool, needs: str) -> str:
        return f"not judged: {needs}" if small else ("yes" if ok else "no")

    # the requirement the study misses, each count beside what it needs
    missed = [f"{corr.takes} take{'s' * (corr.takes != 1)} (needs {MIN_TAKES})"] * (corr.takes < MIN_TAKES)
    missed += [f"{corr.frames} frames (needs {MIN_FRAMES})"] * (corr.frames < MIN_FRAMES)
    needs = ", ".join(missed)

    def rho(a: str, b: str) -> float:
        return float(c[idx[a], idx[b]]) if a in idx and b in idx else float("nan")

    for name in ("MAN_r", "MJE", "MIS"):
        if name in idx:
            others = [abs(c[idx[name], j]) for j in range(len(c)) if j != idx[name]]
            out.append(
                (
                    f"{name} is weakly correlated with the others",
                    verdict(max(others) < WEAK, short, needs),
                    f"max |ρ| {max(others):.2f} ({data})",
                )
            )
    top = max(((a, b) for a in idx for b in idx if a < b), key=lambda p: rho(*p), default=("", ""))
    out.append(
        (
            "SYN_r and HJA_r correlate closely",
            verdict(rho("SYN_r", "HJA_r") > 0.7, short, needs),
            f"ρ {rho('SYN_r', 'HJA_r'):.2f}; highest pair {top[0]}–{top[1]} {rho(*top):.2f} ({data})",
        )
    )
    soa_eea = float(np.mean([rho(a, b) for a in ("SOA_x", "SOA_q") for b in ("EEA", "EEA_r")]))
    out.append(
        ("SOA and EEA correlate", verdict(soa_eea > 0.5, short, needs), f"mean ρ {soa_eea:.2f} ({data})")
    )
    for ranking in rankings:
        out += _opt_beats_jv(ranking)
    return out


def _opt_beats_jv(ranking: Ranking) -> list[tuple[str, str, str]]:
    """The finding "OPT beats JV" in one scenario's ranking, judged on the best approach of each
    with at least :data:`MIN_CELLS` cells; not judged, and said why, where the study ran only one
    of them or neither (the quick study runs no SLSQP)."""
    best = {}
    finding = f"OPT (slsqp) beats JV ({ranking.scenario})"
    for solver in ("slsqp", "jv"):
        rows = [r for r in ranking.rows if r["approach"].split("+")[0].split(" ")[0] == solver]
        top = max(rows, key=lambda r: r["m_hl_f"], default=None)
        if top is None:
            return [(finding, f"not judged: the study ran no {solver} approach", "-")]
        best[solver] = (float(top["m_hl_f"]), int(top["cells"]))
    (opt, n_opt), (jv, n_jv) = best["slsqp"], best["jv"]
    cells = min(n_opt, n_jv)
    verdict = f"not judged: {cells} cells per approach; needs {MIN_CELLS}" if cells < MIN_CELLS else "yes"
    return [
        (
            finding,
            verdict if cells < MIN_CELLS or opt > jv else "no",
            f"best m_hl,f {opt:.3f} vs {jv:.3f} ({cells} cells each)",
        )
    ]


def _img(path: Path) -> str:
    data = base64.b64encode(path.read_bytes()).decode()
    return f'<img src="data:image/png;base64,{data}" alt="{html.escape(path.stem)}">'


def _table(head: Sequence[str], rows: Sequence[Sequence[object]]) -> str:
    cell = lambda v: f"{v:.4g}" if isinstance(v, float) else html.escape(str(v))  # noqa: E731
    out = ["<table><tr>" + "".join(f"<th>{html.escape(h)}</th>" for h in head) + "</tr>"]
    out += ["<tr>" + "".join(f"<td>{cell(v)}</td>" for v in r) + "</tr>" for r in rows]
    return "\n".join(out) + "</table>"


def write_report(
    folder: Path,
    corr: Correlation,
    metric: unified.Metric,
    rankings: Sequence[Ranking],
    summary: dict[str, object],
    failures: Sequence[tuple[str, str]],
) -> Path:
    """Write the PNGs and ``report.html`` into ``folder``; returns the HTML's path."""
    figs = [heatmap(corr, folder / "correlation.png"), dendrogram(corr, folder / "dendrogram.png")]
    figs += [score_bars(r, folder / f"scores_{r.scenario}.png") for r in rankings if r.rows]
    paper = unified.Metric.table3()
    weights = [
        (
            n,
            1.0 / metric.weights[n] if metric.weights[n] else float("inf"),
            1.0 / paper.weights[n],
            metric.x0[n],
            paper.x0[n],
        )
        for n in corr.names
    ]
    parts = [
        "<!doctype html><meta charset='utf-8'><title>hlik study</title>",
        STYLE,
        "<h1>hlik study</h1>",
        _table(["", ""], [(k, v) for k, v in summary.items()]),
        f"<p>Correlation over {corr.takes} take{'s' * (corr.takes != 1)}, {corr.frames} frames: "
        f"{html.escape(corr.deviation_text(MIN_TAKES))}.</p>",
        _img(figs[0]),
        _img(figs[1]),
        "<h2>Derived metric vs Table III</h2>",
        _table(["criterion", "1/w derived", "1/w Table III", "x0 derived", "x0 Table III"], weights),
        "<h2>Paper's findings</h2>",
        _table(
            ["finding", "reproduced", "numbers"],
            findings(corr, rankings),
        ),
    ]
    for ranking, fig in zip([r for r in rankings if r.rows], figs[2:]):
        parts.append(f"<h2>Ranking, {ranking.scenario} scenario (derived metric)</h2>")
        rows = [(r["approach"], r["m_hl"], r["m_f"], r["m_hl_f"], r["cells"]) for r in ranking.rows]
        parts += [_table(["approach", "m_hl", "m_f", "m_hl,f", "cells"], rows), _img(fig)]
    parts.append("<h2>Failed cells</h2>")
    parts.append(_table(["cell", "error"], failures) if failures else "<p>none</p>")
    parts.append(f"<p>hlik {__version__}</p>")
    path = folder / "report.html"
    with atomic_path(path) as tmp:
        tmp.write_text("\n".join(parts), encoding="utf-8")
    return path
