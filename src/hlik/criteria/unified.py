"""The unified metric: logistic normalisation (paper Eq. 1), m_hl (Eq. 2), m_f and m_hl,f.

Each criterion carries its own Table II gamma and Table III x0 and weight
(:mod:`hlik.criteria.registry`); the functional criteria's x0 depend on the scenario (Sec. V).
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType

import numpy as np

from hlik.criteria import registry

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


def midpoints(scenario: str = "pose") -> dict[str, float]:
    """x0 of every criterion scored in ``scenario``: the human-likeness ones, then the functional ones."""
    x0 = {name: registry.criterion_class(name).x0 for name in registry.human_likeness()}
    return {**x0, **FUNCTIONAL_X0[scenario]}


def gamma(name: str, overrides: Mapping[str, float] | None = None) -> float:
    """Table II's gamma of criterion ``name``, unless ``overrides`` gives another."""
    if overrides and name in overrides:
        return float(overrides[name])
    return registry.criterion_class(name).gamma


def logistic(x: np.ndarray, x0: float) -> np.ndarray:
    """Eq. 1's f_x0(x) = 1 / (1 + exp(5 (x - x0) / x0)): 1 at 0, 0.5 at x0, ~0 at 2 x0."""
    z = np.clip(5.0 * (np.asarray(x, dtype=float) - x0) / x0, -700.0, 700.0)
    return 1.0 / (1.0 + np.exp(z))


def score(h: np.ndarray, x0: float) -> float:
    """m_i: the mean of f_x0(h(t)) over the frames (Eq. 1)."""
    return float(np.mean(logistic(h, x0)))


def hierarchical(m: Mapping[str, float]) -> float:
    """m_hl = sum_i w_i m_i (Eq. 2) over the human-likeness criteria (Table III weights)."""
    return float(sum(registry.criterion_class(k).weight * m[k] for k in registry.human_likeness()))


def functional(m: Mapping[str, float], scenario: str = "pose") -> float:
    """m_f: the mean of the functional scores of ``scenario`` (``pose`` or ``relative``)."""
    return float(np.mean([m[k] for k in FUNCTIONAL_X0[scenario]]))


def combined(m_hl: float, m_f: float, alpha: float = ALPHA) -> float:
    """m_hl,f = alpha m_hl + (1 - alpha) m_f."""
    return alpha * m_hl + (1.0 - alpha) * m_f
