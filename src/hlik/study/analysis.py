"""The study's analysis: Spearman correlations of the criteria (Sec. IV-B), Ward's hierarchy and the
weights and x0 it gives (Sec. IV-C, formulas.md §10), and rankings by m_hl,f (Sec. V-A/B)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from types import MappingProxyType

import numpy as np
import pyarrow as pa
from scipy.cluster import hierarchy
from scipy.spatial.distance import squareform
from scipy.stats import spearmanr

from hlik.criteria import registry, unified
from hlik.solvers import SPECS

REACH = 0.10  # m: tracking frames enter the correlation only with both hands this close (Sec. IV-B)
MERGE = 0.15  # merges closer than this in height count as one node (Sec. IV-C)
CUTOFF = 0.75  # below this height a cluster's weight is split equally among its members


def correlation_frames(table: pa.Table, correlation_approaches: set[str]) -> pa.Table:
    """The rows the correlation uses: the correlation approaches' frames, those of tracking solvers
    only where both hands are within :data:`REACH` of their targets (JM's all)."""
    approach = table.column("approach").to_numpy(zero_copy_only=False)
    solver = table.column("solver").to_numpy(zero_copy_only=False)
    near = (table.column("fpos_left").to_numpy() <= REACH) & (table.column("fpos_right").to_numpy() <= REACH)
    mapping = [n for n, s in SPECS.items() if not s.tracks_targets]  # JM: not judged by its reach
    keep = np.isin(approach, list(correlation_approaches)) & (np.isin(solver, mapping) | near)
    return table.filter(pa.array(keep))


def spearman(table: pa.Table, names: tuple[str, ...]) -> np.ndarray:
    """(k, k) Spearman coefficients of the ``h_<name>`` columns over the rows; a constant column
    correlates 0 with the others (1 with itself)."""
    h = np.column_stack([table.column(f"h_{n}").to_numpy() for n in names])
    if len(h) < 3:
        return np.eye(len(names))
    with np.errstate(invalid="ignore", divide="ignore"):
        c = np.atleast_2d(spearmanr(h).statistic)
    c = np.where(np.isfinite(c), c, 0.0)
    np.fill_diagonal(c, 1.0)
    return c


@dataclass(frozen=True)
class Correlation:
    """Spearman matrices of the criteria (paper Fig. 4).

    Attributes:
        names: (k,) criteria, the matrices' order.
        per_robot: Robot name -> (k, k) matrix over that robot's frames.
        mean: (k, k) the per-robot matrices averaged (the paper's C).
        mad_robots, mad_motions: Mean absolute deviation of the off-diagonal coefficients across
            robots, and across motions (per-take matrices over all robots); paper: 0.126 and 0.1.
            NaN with fewer than two robots (takes): there is nothing to deviate from.
        takes: Number of takes the frames come from.
        frames: Number of frames (rows) the matrices are computed over.
    """

    names: tuple[str, ...]
    per_robot: MappingProxyType
    mean: np.ndarray
    mad_robots: float
    mad_motions: float
    takes: int = 0
    frames: int = 0

    def deviation_text(self, min_takes: int = 3) -> str:
        """The deviations across robots and motions against the paper's, with how many robots and
        takes they come from, or why there is none; below ``min_takes`` takes the motions'
        deviation is said to be too few to compare."""
        robots = (
            f"{self.mad_robots:.3f} over {len(self.per_robot)} robots (paper 0.126, 3 robots)"
            if math.isfinite(self.mad_robots)
            else f"none with {len(self.per_robot)} robot (paper 0.126)"
        )
        few = f"; too few takes to compare, needs {min_takes}" if self.takes < min_takes else ""
        motions = (
            f"{self.mad_motions:.3f} over {self.takes} takes (paper 0.1{few})"
            if math.isfinite(self.mad_motions)
            else f"none with {self.takes} take (paper 0.1)"
        )
        return f"mean absolute deviation of the coefficients across robots {robots}, across motions {motions}"


def correlate(frames: pa.Table, names: tuple[str, ...] | None = None) -> Correlation:
    """The :class:`Correlation` of the correlation frames (:func:`correlation_frames`)."""
    names = names or registry.human_likeness()
    per_robot = {r: spearman(_rows(frames, "robot", r), names) for r in _values(frames, "robot")}
    per_take = [spearman(_rows(frames, "take", t), names) for t in _values(frames, "take")]
    mean = np.mean(list(per_robot.values()), axis=0) if per_robot else np.eye(len(names))
    return Correlation(
        names,
        MappingProxyType(per_robot),
        mean,
        _mad(list(per_robot.values())),
        _mad(per_take),
        takes=len(per_take),
        frames=frames.num_rows,
    )


def _values(table: pa.Table, column: str) -> list[str]:
    return sorted(set(table.column(column).to_pylist()))


def _rows(table: pa.Table, column: str, value: str) -> pa.Table:
    return table.filter(pa.compute.equal(table.column(column), value))


def _mad(matrices: list[np.ndarray]) -> float:
    """Mean over the coefficients above the diagonal of their mean absolute deviation across
    matrices; NaN for fewer than two."""
    if len(matrices) < 2:
        return float("nan")
    stack = np.array(matrices)
    upper = np.triu_indices(stack.shape[1], 1)
    values = stack[:, upper[0], upper[1]]
    return float(np.mean(np.abs(values - values.mean(axis=0))))


def ward(c: np.ndarray) -> np.ndarray:
    """Ward's linkage (SciPy's (k - 1, 4) matrix) of the distance D = 1 - C."""
    d = squareform(1.0 - c, checks=False)
    return hierarchy.linkage(np.clip(d, 0.0, None), method="ward")


def hierarchy_weights(
    linkage: np.ndarray, names: tuple[str, ...], merge: float = MERGE, cutoff: float = CUTOFF
) -> dict[str, float]:
    """Eq. 2's weights from a dendrogram by the paper's rule (formulas.md §10).

    From the root down: a node at or above ``cutoff`` splits its weight equally among its children,
    where a child that merged less than ``merge`` below it (and is itself at or above the cut-off)
    is replaced by its own children; a cluster below ``cutoff`` (or a single criterion) splits its
    weight equally among its members. The weights sum to 1.
    """
    root = hierarchy.to_tree(linkage)
    weights: dict[str, float] = {}

    def children(node) -> list:
        out = []
        for child in (node.get_left(), node.get_right()):
            if not child.is_leaf() and child.dist >= cutoff and node.dist - child.dist < merge:
                out += children(child)
            else:
                out.append(child)
        return out

    def assign(node, w: float) -> None:
        if node.is_leaf() or node.dist < cutoff:
            members = node.pre_order()
            for i in members:
                weights[names[i]] = w / len(members)
            return
        kids = children(node)
        for child in kids:
            assign(child, w / len(kids))

    assign(root, 1.0)
    return {n: weights[n] for n in names}


def derive_metric(frames: pa.Table, correlation: Correlation, source: str) -> unified.Metric:
    """Weights from Ward's hierarchy of ``correlation`` and x0 as each criterion's median over the
    correlation ``frames`` (Sec. IV-C)."""
    names = correlation.names
    weights = hierarchy_weights(ward(correlation.mean), names)
    x0 = {n: float(np.median(frames.column(f"h_{n}").to_numpy())) for n in names}
    # a criterion that is 0 on the whole dataset (a robot that never moves a joint) keeps Table III's x0
    table3 = unified.Metric.table3().x0
    x0 = {n: v if v > 0 else table3[n] for n, v in x0.items()}
    return unified.Metric(MappingProxyType(weights), MappingProxyType(x0), source)


@dataclass(frozen=True)
class Ranking:
    """Approaches of one scenario by m_hl,f, each averaged over robots and takes.

    Attributes:
        scenario: ``pose`` or ``relative``.
        rows: Per approach, best first: ``approach``, ``m_hl``, ``m_f``, ``m_hl_f``, ``cells`` and
            ``m`` (criterion -> m_i).
    """

    scenario: str
    rows: tuple[dict, ...]


def rank(table: pa.Table, metric: unified.Metric, scenario: str) -> Ranking:
    """Score every cell of ``scenario`` with ``metric`` (Eq. 1, 2) and rank the approaches."""
    rows = _rows(table, "scenario", scenario)
    x0 = unified.midpoints(scenario, metric)
    cells: dict[str, list[dict]] = {}
    keys = np.char.add(
        np.char.add(rows.column("approach").to_numpy(zero_copy_only=False).astype(str), "|"),
        np.char.add(
            rows.column("robot").to_numpy(zero_copy_only=False).astype(str),
            np.char.add("|", rows.column("take").to_numpy(zero_copy_only=False).astype(str)),
        ),
    )
    h = {k: rows.column(f"h_{k}").to_numpy() for k in x0}
    for key in np.unique(keys):
        sel = keys == key
        m = {k: unified.score(h[k][sel], x0[k]) for k in x0}
        m_hl, m_f = unified.hierarchical(m, metric), unified.functional(m, scenario)
        score = {"m": m, "m_hl": m_hl, "m_f": m_f, "m_hl_f": unified.combined(m_hl, m_f)}
        cells.setdefault(str(key).split("|")[0], []).append(score)
    out = []
    for approach, scores in cells.items():
        row: dict = {"approach": approach, "cells": len(scores)}
        row |= {f: float(np.mean([s[f] for s in scores])) for f in ("m_hl", "m_f", "m_hl_f")}
        row["m"] = {k: float(np.mean([s["m"][k] for s in scores])) for k in x0}
        out.append(row)
    out.sort(key=lambda r: -r["m_hl_f"])
    return Ranking(scenario, tuple(out))
