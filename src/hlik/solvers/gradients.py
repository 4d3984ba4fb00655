"""A term's cost of one sample and its gradient in q, whole and per arm: what JV's null space and
SLSQP's losses and constraints read of a :class:`~hlik.criteria.base.Term`.

A term gives its residual and Jacobian (:meth:`~hlik.criteria.base.Term.exact` for the exact
derivative), the cost h of a residual and dh/de (:meth:`~hlik.criteria.base.Term.metrics`, the
stand-in where the solvers minimise one); here h and dh/dq of one sample follow by the chain rule,
and per part (each arm's rows, ``Term.parts``): ``parts * h(e_p)``, whose mean is h. Where a term
sets ``gradient_cap``, each dh/dq is scaled down to that norm (EEA, as the paper caps the elevation
gradients, Sec. IV-A).
"""

from __future__ import annotations

import numpy as np

from hlik.criteria.base import Sample, Term
from hlik.robot.state import RobotState


def metric(term: Term, e: np.ndarray) -> tuple[float, np.ndarray]:
    """h and dh/de (m,) of one residual ``e`` (m,) (:meth:`Term.metrics`)."""
    h, dh_de = term.metrics(e[None])
    return float(h[0]), dh_de[0]


def gradient(term: Term, state: RobotState, sample: Sample) -> tuple[float, np.ndarray]:
    """The cost h of one sample and its gradient dh/dq (n,)."""
    return gradient_of(term, *term.exact(state, sample))


def gradient_of(term: Term, e: np.ndarray, jac: np.ndarray) -> tuple[float, np.ndarray]:
    """:func:`gradient` from :meth:`Term.exact`'s residual ``e`` (m,) and Jacobian ``jac`` (m, n)."""
    h, dh_de = metric(term, e)
    return h, _capped(term, dh_de @ jac)


def part_metric(term: Term, e: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each part's cost ``parts * h(e_p)`` of a residual ``e`` (m,) or (F, m): (P,) or (F, P), and
    d/de: (P, m) or (F, P, m).

    Their mean is h(e). A solver that puts each through its own loss keeps a smooth objective
    where the loss of the mean has a kink: l(|a| + |b|) at a = 0 when b != 0."""
    if term.parts == 1:
        h, dh_de = term.metrics(e.reshape(-1, e.shape[-1]))
        return h.reshape(*e.shape[:-1], 1), dh_de.reshape(*e.shape[:-1], 1, e.shape[-1])
    rows = term.part_rows(e.shape[-1])
    if term.part_form == "norm":  # each part's cost is the norm of its rows: no split needed
        norms = np.stack([np.sqrt(np.einsum("...i,...i->...", e[..., r], e[..., r])) for r in rows], -1)
        grad = np.zeros((*e.shape[:-1], len(rows), e.shape[-1]))
        for p, r in enumerate(rows):
            grad[..., p, r] = e[..., r] / np.maximum(norms[..., p, None], 1e-12)
        return term.norm_scale * norms, term.norm_scale * grad
    split = np.zeros((*e.shape[:-1], len(rows), e.shape[-1]))
    for p, r in enumerate(rows):
        split[..., p, r] = e[..., r]
    h, dh_de = term.metrics(split.reshape(-1, e.shape[-1]))
    return term.parts * h.reshape(split.shape[:-1]), term.parts * dh_de.reshape(split.shape)


def part_gradients(term: Term, state: RobotState, sample: Sample) -> tuple[np.ndarray, np.ndarray]:
    """Each part's cost (P,) of one sample (:func:`part_metric`) and its gradient d/dq (P, n)."""
    return part_gradients_of(term, *term.exact(state, sample))


def part_gradients_of(term: Term, e: np.ndarray, jac: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`part_gradients` from :meth:`Term.exact`'s residual ``e`` (m,) and Jacobian ``jac`` (m, n)."""
    if term.parts == 1:
        cost, grad = gradient_of(term, e, jac)
        return np.array([cost]), grad[None]
    costs, dh_de = part_metric(term, e)
    return costs, _capped(term, dh_de @ jac)


def _capped(term: Term, grad: np.ndarray) -> np.ndarray:
    """``grad`` (..., n), each row scaled down to the term's ``gradient_cap`` if it is longer."""
    cap = term.gradient_cap
    if cap is None:
        return grad
    norm = np.linalg.norm(grad, axis=-1, keepdims=True)
    return grad * np.minimum(1.0, cap / np.maximum(norm, 1e-300))
