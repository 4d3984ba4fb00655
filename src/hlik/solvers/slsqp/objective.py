"""SLSQP's objective: one groove loss per term (and arm), its value and exact gradient from one
forward-kinematics pass, and the Gauss-Newton chart each frame is solved in."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import mujoco
import numpy as np

from hlik.criteria import registry, unified
from hlik.criteria.base import Sample, Term
from hlik.criteria.elbows import ElbowsAhead
from hlik.criteria.functional import fORI, fORI_off, fPOS, fPOS_off
from hlik.criteria.joints import TrunkUpright
from hlik.criteria.learned import Learned
from hlik.criteria.smoothness import ACCELERATION, JERK, VELOCITY, Smoothness
from hlik.robot.model import Robot
from hlik.robot.state import robot_state
from hlik.solvers.frames import FIRST_FRAME_SCENARIO, first_frame_terms
from hlik.solvers.gradients import gradient_of, metric, part_gradients_of, part_metric
from hlik.solvers.settings import SLSQPSettings
from hlik.solvers.slsqp.groove import groove, groove_curvature, groove_secant

# Sec. IV-A's gamma_p = 10 for the TCP position. The relative position and the elbows behind the
# back (m, like fPOS) get it too:
# with 1 the groove's well (c = 0.1) is 10 cm wide and SLSQP leaves fPOS^off at 10-50 cm on the
# demo; with 10 it is a few mm (Sec. V-B's x0: 3 cm).
POSITION_TERMS = ("fPOS", "fPOS_off", "elbows")  # lengths, m

# objective_scale's factor over the mean Gauss-Newton diagonal: an initial Hessian that is too large
# only shortens the first steps, one too small overshoots; 10 needed the fewest evaluations (1, 10,
# 3e4 fixed and per-frame tried on ARMAR-6, ARMAR-III and 2-Panda, Cut take, both bundled stacks).
SCALE_FACTOR = 10.0


def objective_scale(weights: np.ndarray, gammas: np.ndarray, h: np.ndarray, dh_dq: np.ndarray) -> float:
    """The divisor that gives the objective a Hessian of order one, for SLSQP's identity start.

    ``SCALE_FACTOR`` times the mean diagonal of the Gauss-Newton Hessian
    ``sum_i w_i gamma_i² l''(gamma_i h_i) grad h_i grad h_iᵀ`` at the frame's start, from the costs
    ``h`` (m,) and their gradients ``dh_dq`` (m, n); at least 1e-9.
    """
    curvature = weights * gammas**2 * groove_curvature(gammas * h)
    return max(SCALE_FACTOR * float(curvature @ np.sum(dh_dq**2, axis=1)) / dh_dq.shape[1], 1e-9)


@dataclass(frozen=True)
class Loss:
    """One summand ``weight * groove(gamma * h)`` of the objective, h from ``term``."""

    term: Term
    weight: float
    gamma: float


def build_losses(
    robot: Robot, settings: SLSQPSettings, learned: Learned | None, first: bool = False
) -> list[Loss]:
    """The losses of ``settings`` with non-zero weight; ``first``: those of the first frame.

    The first frame (:func:`~hlik.solvers.frames.first_frame_terms`) has no term of motion, and
    in ``relative`` tracks the TCP poses "as in Section V-A": with the default (pose) weights, and
    the same criteria.
    """
    if first and settings.scenario != FIRST_FRAME_SCENARIO:
        pose = SLSQPSettings()
        settings = replace(
            pose, criteria=settings.criteria, gamma=settings.gamma, position_gamma=settings.position_gamma
        )
    weighted: list[tuple[Term, float]] = [
        (fPOS(), settings.position_cost),
        (fORI(), settings.orientation_cost),
        (fPOS_off(), settings.relative_position_cost),
        (fORI_off(), settings.relative_orientation_cost),
        (Smoothness(VELOCITY, robot, "velocity"), settings.velocity_cost),
        (Smoothness(ACCELERATION, robot, "acceleration"), settings.acceleration_cost),
        (Smoothness(JERK, robot, "jerk"), settings.jerk_cost),
    ]
    if robot.extra_joints:
        weighted.append((TrunkUpright(robot), settings.trunk_cost))
    weighted.append((ElbowsAhead(settings.elbow_allowance), settings.elbow_cost))
    weight = settings.criterion_cost / max(len(settings.criteria), 1)
    weighted += [(registry.criterion(name, robot, learned), weight) for name in settings.criteria]
    if first:
        weighted = first_frame_terms(weighted)
    gamma = {name: settings.position_gamma for name in POSITION_TERMS}
    gamma |= {name: unified.gamma(name, settings.gamma) for name in settings.criteria}
    return [Loss(t, float(w), float(gamma.get(t.name, 1.0))) for t, w in weighted if w > 0]


def loss_curvature(loss: Loss, e: np.ndarray, split: bool, eps: float = 1e-6) -> np.ndarray:
    """(m, m) Hessian of ``loss`` (its parts' losses if ``split``) in the residual ``e`` (m,), PSD.

    Closed form where each part's cost is the norm of its rows (``Term.part_form = "norm"``, times
    ``Term.norm_scale``): ``g² [l'(x)/x (I - u u^T) + l''(x) u u^T]`` on them, g = gamma norm_scale,
    x = g |e_p|, u = e_p / |e_p|, smooth through e_p = 0; and for the mean of squares. Else by
    central differences of the loss's analytic gradient (``eps`` relative to the residual's size),
    negative curvature clipped.
    """
    term, gamma, m = loss.term, loss.gamma, len(e)
    rows = term.part_rows(m) if split else (np.arange(m),)
    form = term.part_form or ("squares" if _least_squares(term) else None)
    if not split and term.parts > 1:
        form = None  # the loss of the mean over the parts
    if form == "norm":
        phi = np.zeros((m, m))
        for r in rows:
            part = e[r]
            norm = float(np.sqrt(part @ part))
            u = part / norm if norm > 0.0 else np.zeros(len(r))
            x = gamma * term.norm_scale * norm
            across, along = groove_secant(x), float(groove_curvature(np.array(x)))
            phi[np.ix_(r, r)] = across * np.eye(len(r)) + (along - across) * np.outer(u, u)
        return phi * loss.weight * (gamma * term.norm_scale) ** 2 / len(rows)
    if form == "squares":
        g = 2.0 * e / m
        x = gamma * float(e @ e) / m
        slope = float(groove(x)[1])
        return loss.weight * (
            gamma * slope * 2.0 / m * np.eye(m)
            + gamma**2 * float(groove_curvature(np.array(x))) * np.outer(g, g)
        )
    step = eps * max(1.0, float(np.max(np.abs(e), initial=0.0)))
    batch = e + step * np.concatenate([np.eye(m), -np.eye(m)])
    if split:
        h, dh_de = part_metric(term, batch)  # (2m, P), (2m, P, m)
    else:
        whole, d_whole = term.metrics(batch)
        h, dh_de = whole[:, None], d_whole[:, None]
    slope = groove(gamma * h)[1] * gamma * loss.weight / h.shape[1]
    d_loss = np.einsum("bp,bpm->bm", slope, dh_de)
    phi = (d_loss[:m] - d_loss[m:]) / (2.0 * step)
    w, v = np.linalg.eigh(0.5 * (phi + phi.T))
    return (v * np.maximum(w, 0.0)) @ v.T


def _least_squares(term: Term) -> bool:
    """Whether the solvers minimise the mean of squares of ``term``'s residual (Term's own cost)."""
    kind = type(term)
    return kind.cost is Term.cost and kind.metrics is Term.metrics


class Objective:
    """``sum_i w_i groove(gamma_i h_i(q))`` of one frame and its gradient; NLopt's callback.

    Set the frame with :meth:`reset` before optimising. Counts NLopt's evaluations.
    """

    def __init__(
        self,
        robot: Robot,
        losses: Sequence[Loss],
        gradients: str = "analytic",
        fd_step: float = 1e-7,
        precondition: str = "gauss_newton",
    ):
        self.robot, self.losses, self.fd_step = robot, tuple(losses), fd_step
        self.precondition = precondition
        self.analytic = gradients == "analytic"
        # criteria whose Jacobian holds a prediction fixed: h is differentiated numerically, capped
        caps = [getattr(loss.term, "numeric_gradient_cap", None) for loss in self.losses]
        numeric = [i for i, cap in enumerate(caps) if cap is not None]
        self.caps = np.array([caps[i] for i in numeric])
        # one FK pass computes only the site Jacobians the terms read (for fd: their values read)
        self.sites = loss_sites(loss.term.sites for loss in self.losses)
        self.value_sites = loss_sites(loss.term.value_sites for loss in self.losses)
        # a loss over both arms is one loss per arm, weighted half (gradients.part_metric says why): h
        # and the weights below are per piece, loss i's at slots[i]:slots[i + 1]
        self.split = tuple(loss.term.parts > 1 and i not in numeric for i, loss in enumerate(self.losses))
        counts = [loss.term.parts if split else 1 for loss, split in zip(self.losses, self.split)]
        self.slots = np.concatenate([[0], np.cumsum(counts)])
        self.weights = np.repeat([loss.weight / c for loss, c in zip(self.losses, counts)], counts)
        self.gammas = np.repeat([loss.gamma for loss in self.losses], counts)
        self.numeric = tuple(int(self.slots[i]) for i in numeric)
        self._numeric_losses = tuple(numeric)
        self.data = mujoco.MjData(robot.model)
        self.reset()

    def reset(self, frame: Sample | None = None, q0: np.ndarray | None = None) -> None:
        """Start a frame: forget the evaluation count. With ``q0`` (n,),
        NLopt's view of the frame is set up at ``q0`` as :attr:`precondition` says: :attr:`chart`
        (``gauss_newton``) and :attr:`scale`."""
        self.frame = frame
        self.evaluations, self.scale = 0, 1.0
        self.chart: Chart | None = None
        self._start: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        if q0 is None or frame is None:
            return
        if self.precondition == "gauss_newton":
            hessian, h, dh_dq = self._gauss_newton_pass(q0)
            self.chart = Chart.at(q0, hessian)
            self._start = (q0.copy(), h, dh_dq)  # NLopt evaluates x = 0 first: kept, not redone
        if self.precondition == "scale" or (self.precondition == "gauss_newton" and self.chart is None):
            self.scale = objective_scale(self.weights, self.gammas, *self.costs_and_gradients(q0))

    def gauss_newton(self, q: np.ndarray) -> np.ndarray:
        """(n, n) the objective's Gauss-Newton Hessian at ``q`` (n,): ``sum_i J_i^T Phi_i J_i``.

        J_i is term i's exact Jacobian and Phi_i the Hessian of its losses in its residual space
        (:func:`loss_curvature`). Exact for least squares; for a norm cost it keeps the curvature
        across the error that the rank-one ``grad h grad h^T`` misses (the norm's own Hessian).
        """
        return self._gauss_newton_pass(q)[0]

    def _gauss_newton_pass(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`gauss_newton` and :meth:`costs_and_gradients` at ``q`` (n,) from one pass."""
        state = robot_state(self.robot, q, True, self.data, self.sites)
        m = int(self.slots[-1])
        hessian, h, dh_dq = np.zeros((len(q), len(q))), np.empty(m), np.empty((m, len(q)))
        for i, (loss, split) in enumerate(zip(self.losses, self.split)):
            e, jac = loss.term.exact(state, self.sample)
            hessian += jac.T @ loss_curvature(loss, e, split) @ jac
            self._piece_gradients(i, e, jac, h, dh_dq)
        if self.numeric:
            dh_dq[list(self.numeric)] = self._numeric_gradient(q, h[list(self.numeric)])
        return hessian, h, dh_dq

    def _piece_gradients(
        self, i: int, e: np.ndarray, jac: np.ndarray, h: np.ndarray, dh_dq: np.ndarray
    ) -> None:
        """Loss ``i``'s costs and gradients, into its pieces of ``h`` (m,) and ``dh_dq`` (m, n), from
        its term's exact residual ``e`` and Jacobian ``jac``."""
        term, piece = self.losses[i].term, slice(self.slots[i], self.slots[i + 1])
        if self.split[i]:
            h[piece], dh_dq[piece] = part_gradients_of(term, e, jac)
        else:
            h[piece.start], dh_dq[piece.start] = gradient_of(term, e, jac)

    @property
    def sample(self) -> Sample:
        if self.frame is None:
            raise RuntimeError("Objective.reset(sample) must be called before evaluating")
        return self.frame

    def costs(self, q: np.ndarray, which: Sequence[int] | None = None) -> np.ndarray:
        """The costs h at ``q`` (n,) of the losses ``which`` (all by default), per piece, no Jacobians
        needed."""
        which = range(len(self.losses)) if which is None else which
        state = robot_state(self.robot, q, True, self.data, self.value_sites)
        h = []
        for i in which:
            term = self.losses[i].term
            e = term(state, self.sample)[0]
            h.append(part_metric(term, e)[0] if self.split[i] else [metric(term, e)[0]])
        return np.concatenate(h)

    def value(self, q: np.ndarray) -> float:
        """The objective at ``q`` (n,)."""
        return self._total(self.costs(q))[0]

    def costs_and_gradients(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The costs h (m,) at ``q`` (n,) per piece and their gradients (m, n) from the terms'
        Jacobians."""
        if self._start is not None and np.array_equal(q, self._start[0]):
            return self._start[1].copy(), self._start[2].copy()
        state = robot_state(self.robot, q, True, self.data, self.sites)
        m = int(self.slots[-1])
        h, dh_dq = np.empty(m), np.empty((m, len(q)))
        for i, loss in enumerate(self.losses):
            self._piece_gradients(i, *loss.term.exact(state, self.sample), h, dh_dq)
        if self.numeric:
            dh_dq[list(self.numeric)] = self._numeric_gradient(q, h[list(self.numeric)])
        return h, dh_dq

    def value_and_gradient(self, q: np.ndarray) -> tuple[float, np.ndarray]:
        """The objective at ``q`` (n,) and its gradient (n,) from the terms' Jacobians."""
        h, dh_dq = self.costs_and_gradients(q)
        total, slopes = self._total(h)
        return total, slopes @ dh_dq

    def fd_gradient(self, q: np.ndarray, f0: float) -> np.ndarray:
        """Forward differences (n,) of the objective at ``q`` whose value is ``f0``: n evaluations."""
        grad, x = np.empty(len(q)), q.copy()
        for j in range(len(q)):
            x[j] += self.fd_step
            grad[j] = (self.value(x) - f0) / self.fd_step
            x[j] = q[j]
        return grad

    def _numeric_gradient(self, q: np.ndarray, h0: np.ndarray) -> np.ndarray:
        """Forward differences (k, n) of the costs of the losses :attr:`numeric`, valued ``h0`` (k,)."""
        dh_dq, x = np.empty((len(h0), len(q))), q.copy()
        for j in range(len(q)):
            x[j] += self.fd_step
            dh_dq[:, j] = (self.costs(x, self._numeric_losses) - h0) / self.fd_step
            x[j] = q[j]
        norms = np.linalg.norm(dh_dq, axis=1)
        return dh_dq * np.minimum(1.0, self.caps / np.maximum(norms, 1e-300))[:, None]

    def _total(self, h: np.ndarray) -> tuple[float, np.ndarray]:
        """The objective of costs ``h`` (m,) and its derivatives (m,) with respect to them."""
        value, slope = groove(self.gammas * h)
        return float(self.weights @ value), self.weights * self.gammas * slope

    def __call__(self, x: np.ndarray, grad: np.ndarray) -> float:
        """NLopt's callback: the objective at q = :attr:`chart`'s q(x) (or x) divided by
        :attr:`scale`; fills ``grad`` with d/dx (same scale) in place when it is not empty."""
        self.evaluations += 1
        q = x if self.chart is None else self.chart.q(x)
        g: np.ndarray | None = None
        if grad.size and self.analytic:
            f, g = self.value_and_gradient(q)
        else:
            f = self.value(q)
            g = self.fd_gradient(q, f) if grad.size else None
        if g is not None:
            grad[:] = (g if self.chart is None else g @ self.chart.T) / self.scale
        return f / self.scale


@dataclass(frozen=True)
class Chart:
    """One frame's variables for NLopt: ``q = origin + T x`` with ``T = L^-T`` for the Cholesky
    factor L of a Hessian estimate H = L L^T, so the objective's Hessian in x is about I, NLopt's
    SLSQP start (the module docstring says why).

    Attributes:
        origin: (n,) the frame's start, x = 0.
        T: (n, n) upper triangular.
    """

    origin: np.ndarray
    T: np.ndarray

    @classmethod
    def at(cls, origin: np.ndarray, hessian: np.ndarray) -> Chart | None:
        """The chart at ``origin`` (n,) for ``hessian`` (n, n), regularised by 1e-6 of its mean
        diagonal; None if it is not positive definite even so (or not finite)."""
        h = 0.5 * (hessian + hessian.T)
        h[np.diag_indices_from(h)] += 1e-6 * max(float(np.trace(h)) / len(h), 1e-12)
        try:
            lower = np.linalg.cholesky(h)
        except np.linalg.LinAlgError:
            return None
        t = np.linalg.inv(lower).T
        return cls(origin.copy(), t) if np.all(np.isfinite(t)) else None

    def q(self, x: np.ndarray) -> np.ndarray:
        """(n,) the configuration at ``x`` (n,)."""
        return self.origin + self.T @ x


def loss_sites(groups) -> tuple[int, ...]:
    return tuple(sorted({i for group in groups for i in group}))
