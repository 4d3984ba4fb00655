"""The unified metric: logistic normalisation (paper Eq. 1), m_hl (Eq. 2, Table III), m_f and m_hl,f.

Constants are the paper's: Table II (gamma, used by the solvers), Table III (x0 and hierarchical
weights), Sec. V (x0 of the functional criteria per scenario).
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType

import numpy as np

CRITERIA = ("EEA", "SOA_x", "SOA_q", "HJL", "SYN", "MIS", "MJE", "HJA_r", "SYN_r", "EEA_r", "MAN_r")

# Table III: logistic mid-points and inverse hierarchical weights.
X0: Mapping[str, float] = MappingProxyType(
    dict(zip(CRITERIA, (0.3, 0.2, 0.34, 0.48, 0.12, 0.49, 2e-4, 0.35, 0.47, 0.1, 1.9)))
)
WEIGHTS: Mapping[str, float] = MappingProxyType(
    {k: 1.0 / w for k, w in zip(CRITERIA, (20, 20, 20, 15, 15, 5, 5, 30, 30, 20, 5))}
)
# Table II: scaling weights of the criteria as solver costs (MJE is part of OPT itself).
GAMMA: Mapping[str, float] = MappingProxyType(
    dict(zip(CRITERIA[:6] + CRITERIA[7:], (4, 10, 2, 1, 6, 1, 2, 2, 6, 0.5)))
)
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
    """x0 of every criterion scored in ``scenario``: the 11 of Table III, then the functional ones."""
    return {**X0, **FUNCTIONAL_X0[scenario]}


def logistic(x: np.ndarray, x0: float) -> np.ndarray:
    """Eq. 1's f_x0(x) = 1 / (1 + exp(5 (x - x0) / x0)): 1 at 0, 0.5 at x0, ~0 at 2 x0."""
    z = np.clip(5.0 * (np.asarray(x, dtype=float) - x0) / x0, -700.0, 700.0)
    return 1.0 / (1.0 + np.exp(z))


def score(h: np.ndarray, x0: float) -> float:
    """m_i: the mean of f_x0(h(t)) over the frames (Eq. 1)."""
    return float(np.mean(logistic(h, x0)))


def hierarchical(m: Mapping[str, float]) -> float:
    """m_hl = sum_i w_i m_i (Eq. 2) over the 11 criteria."""
    return float(sum(WEIGHTS[k] * m[k] for k in CRITERIA))


def functional(m: Mapping[str, float], scenario: str = "pose") -> float:
    """m_f: the mean of the functional scores of ``scenario`` (``pose`` or ``relative``)."""
    return float(np.mean([m[k] for k in FUNCTIONAL_X0[scenario]]))


def combined(m_hl: float, m_f: float, alpha: float = ALPHA) -> float:
    """m_hl,f = alpha m_hl + (1 - alpha) m_f."""
    return alpha * m_hl + (1.0 - alpha) * m_f
