"""The unified metric: logistic normalisation (paper Eq. 1), m_hl (Eq. 2), m_f and m_hl,f.

Each criterion carries its own Table II gamma and Table III x0 and weight
(:mod:`hlik.criteria.registry`); the functional criteria's x0 depend on the scenario (Sec. V). A
:class:`Metric` holds another set of weights and x0 (one a study derived), read from and written to
TOML; :meth:`Metric.table3` is the paper's.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import TYPE_CHECKING

import numpy as np

from hlik.criteria import registry
from hlik.util.errors import HlikError, SettingsError
from hlik.util.tomlfile import read_toml, unknown_key

if TYPE_CHECKING:
    from hlik.criteria.base import Criterion

# Sec. V: functional criteria and their mid-points, per scenario.
FUNCTIONAL_X0: Mapping[str, Mapping[str, float]] = MappingProxyType(
    {
        "pose": MappingProxyType({"fJLA": 0.5, "fPOS": 0.03, "fORI": 0.35}),
        "relative": MappingProxyType(
            {"fJLA": 0.5, "fPOS_off": 0.03, "fORI_off": 0.35, "fPOS": 0.3, "fORI": 1.0}
        ),
    }
)
ALPHA = 0.5


def check_scenario(scenario: str) -> None:
    """Raises:
    SettingsError: ``scenario`` is none of :data:`FUNCTIONAL_X0`'s (``pose``, ``relative``)."""
    if scenario not in FUNCTIONAL_X0:
        raise SettingsError(f"unknown scenario {scenario!r}; choose one of: {', '.join(FUNCTIONAL_X0)}")


def midpoints(scenario: str = "pose", metric: Metric | None = None) -> dict[str, float]:
    """x0 of every criterion scored in ``scenario``: the human-likeness ones (``metric``'s, default
    Table III's), then the functional ones."""
    return {**(metric or Metric.table3()).x0, **FUNCTIONAL_X0[scenario]}


def gamma(name: str, overrides: Mapping[str, float] | None = None) -> float:
    """Table II's gamma of criterion ``name``, unless ``overrides`` gives another."""
    if overrides and name in overrides:
        return float(overrides[name])
    return registry.criterion_class(name).gamma


def weighted_criteria(
    names: Sequence[str],
    robot: object,
    learned: object | None,
    cost: float,
    overrides: Mapping[str, float] | None,
) -> list[tuple[Criterion, float]]:
    """Each criterion of ``names`` for ``robot`` (:func:`~hlik.criteria.registry.criterion`, built
    from ``learned``) with the paper's weight ``gamma_i * cost / k`` (Sec. V: the solver's criterion
    weight shared among the k criteria), gamma_i by :func:`gamma`."""
    return [(registry.criterion(n, robot, learned), gamma(n, overrides) * cost / len(names)) for n in names]


def logistic(x: np.ndarray, x0: float) -> np.ndarray:
    """Eq. 1's f_x0(x) = 1 / (1 + exp(5 (x - x0) / x0)): 1 at 0, 0.5 at x0, ~0 at 2 x0."""
    z = np.clip(5.0 * (np.asarray(x, dtype=float) - x0) / x0, -700.0, 700.0)
    return 1.0 / (1.0 + np.exp(z))


def score(h: np.ndarray, x0: float) -> float:
    """m_i: the mean of f_x0(h(t)) over the frames (Eq. 1)."""
    return float(np.mean(logistic(h, x0)))


@dataclass(frozen=True)
class Metric:
    """Weights w_i (Eq. 2, summing to 1) and mid-points x0_i (Eq. 1) of the human-likeness criteria.

    Attributes:
        weights: Criterion name -> w_i.
        x0: Criterion name -> x0_i, in the units of the criterion's cost h_i.
        source: Where they come from (``Table III`` or the study that derived them).
    """

    weights: Mapping[str, float]
    x0: Mapping[str, float]
    source: str = "Table III"

    @classmethod
    def table3(cls) -> Metric:
        """The paper's: every registered criterion's own Table III weight and x0."""
        names = registry.human_likeness()
        return cls(
            MappingProxyType({k: registry.criterion_class(k).weight for k in names}),
            MappingProxyType({k: registry.criterion_class(k).x0 for k in names}),
        )

    def to_toml(self) -> str:
        """The TOML text :func:`load_metric` reads back exactly."""
        lines = [f"source = {_toml_string(self.source)}", "", "[weights]"]
        lines += [f"{k} = {v!r}" for k, v in self.weights.items()]
        lines += ["", "[x0]"] + [f"{k} = {v!r}" for k, v in self.x0.items()]
        return "\n".join(lines) + "\n"


def _toml_string(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def load_metric(path: Path) -> Metric:
    """A :class:`Metric` from a TOML file (``[weights]`` and ``[x0]`` tables, ``source``).

    Every registered human-likeness criterion needs a weight and a positive x0; the weights are
    non-negative and sum to 1 (within 1e-6).

    Raises:
        HlikError: one line naming the file and the problem.
    """
    path = Path(path)
    raw = read_toml(path, "metric")
    if problem := unknown_key(raw, ("source", "weights", "x0"), "the top-level table"):
        raise HlikError(f"{path}: {problem}")
    names = registry.human_likeness()
    tables = {}
    for key in ("weights", "x0"):
        table = raw.get(key)
        if not isinstance(table, dict):
            raise HlikError(f"{path}: needs a [{key}] table of criterion = number")
        if problem := unknown_key(table, names, f"[{key}]"):  # a misspelt one first: SYNN, not "missing SYN"
            raise HlikError(f"{path}: {problem}")
        if missing := set(names) - set(table):
            raise HlikError(f"{path}: [{key}] missing {', '.join(sorted(missing))}")
        for k, v in table.items():
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v):
                raise HlikError(f"{path}: {key}.{k} must be a number, not {v!r}")
        tables[key] = {k: float(table[k]) for k in names}
    total = sum(tables["weights"].values())
    if any(v < 0 for v in tables["weights"].values()) or abs(total - 1.0) > 1e-6:
        raise HlikError(f"{path}: [weights] must be non-negative and sum to 1, not {total:.6g}")
    if any(v <= 0 for v in tables["x0"].values()):
        raise HlikError(f"{path}: [x0] must be positive")
    source = raw.get("source", path.name)
    return Metric(MappingProxyType(tables["weights"]), MappingProxyType(tables["x0"]), str(source))


def hierarchical(m: Mapping[str, float], metric: Metric | None = None) -> float:
    """m_hl = sum_i w_i m_i (Eq. 2) over the human-likeness criteria (``metric``'s weights, default
    Table III's)."""
    weights = (metric or Metric.table3()).weights
    return float(sum(weights[k] * m[k] for k in registry.human_likeness()))


def functional(m: Mapping[str, float], scenario: str = "pose") -> float:
    """m_f: the mean of the functional scores of ``scenario`` (``pose`` or ``relative``)."""
    return float(np.mean([m[k] for k in FUNCTIONAL_X0[scenario]]))


def combined(m_hl: float, m_f: float, alpha: float = ALPHA) -> float:
    """m_hl,f = alpha m_hl + (1 - alpha) m_f."""
    return alpha * m_hl + (1.0 - alpha) * m_f
