"""SLSQP retargeting: the paper's OPT, RelaxedIK groove losses minimised per frame with NLopt.

Per frame, SLSQP minimises ``sum_i w_i l(gamma_i h_i(q))`` over the joint angles q within the joint
limits, where each h_i is the scalar cost of a term (:mod:`hlik.criteria`): the TCP pose or relative
pose errors, RelaxedIK's minimum velocity, acceleration and jerk toward the previous solutions, and
the chosen human-likeness criteria; l is the groove loss. A cost that is the mean over both arms
(fPOS, fORI, EEA, SOA_x, MAN^r, MJE) enters as one loss per arm, each with half the weight
(:meth:`~hlik.criteria.base.Term.part_metric`): the loss of the mean, l(|a| + |b|), has a kink
wherever one arm is on its target and the other is not, which at the optimum is everywhere, and
SLSQP crawled along it (ARMAR-6, Cut take: 65 evaluations a frame, 18 with the split). One
forward-kinematics pass per evaluation gives every h_i and, with ``gradients="analytic"``, its
exact gradient (:meth:`~hlik.criteria.base.Term.exact`); ``gradients="fd"`` uses forward
differences of the objective instead, as the paper and RelaxedIK do.
Frames are warm-started from the previous solution; a frame where NLopt fails keeps the best finite
configuration it evaluated (or the previous solution) and is reported.

NLopt's SLSQP starts each frame's quasi-Newton model from the identity Hessian, and the objective's
is 10^3-10^5 times larger and far from round. Each frame is therefore solved in the variables x of
a :class:`Chart`, ``q = q_start + L^-T x`` with L the Cholesky factor of the objective's
Gauss-Newton Hessian at the start (:meth:`Objective.gauss_newton`), where the Hessian is about the
identity: SLSQP's first step is a Gauss-Newton step. The joint box becomes linear inequality
constraints. At the paper's ``ftol_rel = 1e-6`` a frame then takes 4-5 evaluations (Cut and Close
takes, the three robots, with and without criteria) where it took 44-72, with equal or better
scores (``bench/slsqp_precondition.py``; ``precondition="scale"`` only divides the objective by
:func:`objective_scale`, the earlier remedy).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from types import MappingProxyType

import mujoco
import nlopt
import numpy as np

from hlik.criteria import registry, unified
from hlik.criteria.base import Sample, Term
from hlik.criteria.functional import fORI, fORI_off, fPOS, fPOS_off
from hlik.criteria.joints import TrunkUpright
from hlik.criteria.learned import Learned, learn
from hlik.criteria.smoothness import ACCELERATION, JERK, VELOCITY, Smoothness
from hlik.errors import SettingsError
from hlik.problem.problem import Problem
from hlik.robot.collision import CollisionPairs, DistanceBounds, collision_pairs, near_pairs
from hlik.robot.model import Robot
from hlik.robot.state import robot_state
from hlik.solvers.base import ConfiguredSolver, SolverResult, check_settings
from hlik.solvers.frames import FrameResult, JointBox, collision_floors, hand_band, track
from hlik.solvers.limits import LimitSettings, MotionLimits

# Sec. IV-A's gamma_p = 10 for the TCP position. The relative position (m, like fPOS) gets it too:
# with 1 the groove's well (c = 0.1) is 10 cm wide and SLSQP leaves fPOS^off at 10-50 cm on the
# demo; with 10 it is a few mm (Sec. V-B's x0: 3 cm).
POSITION_TERMS = ("fPOS", "fPOS_off")

# NLopt exceptions that end one frame, not the run, and the result code each stands for. NLopt's
# generic failure also comes as a plain RuntimeError("nlopt failure"): only that message counts, so
# that a RuntimeError raised by hlik's own code in a callback (a bug) stops the run instead of
# passing for a failed frame.
NLOPT_ERRORS: Mapping[type[Exception], int] = MappingProxyType(
    {
        nlopt.RoundoffLimited: nlopt.ROUNDOFF_LIMITED,
        nlopt.ForcedStop: nlopt.FORCED_STOP,
        nlopt.runtime_error: nlopt.FAILURE,
        RuntimeError: nlopt.FAILURE,
    }
)
NLOPT_FAILURE_MESSAGE = "nlopt failure"


def _nlopt_code(err: Exception) -> int | None:
    """NLopt's result code for an exception NLopt raised, None for any other."""
    for kind, code in NLOPT_ERRORS.items():
        if isinstance(err, kind):
            if kind is RuntimeError and str(err) != NLOPT_FAILURE_MESSAGE:
                return None
            return code
    return None


GROOVE_C, GROOVE_R = 0.1, 10.0  # the paper's c and r (Sec. IV-A)


def groove(
    x: float | np.ndarray, c: float = GROOVE_C, r: float = GROOVE_R, s: float = 0.0, d: int = 2, g: int = 2
) -> tuple[float | np.ndarray, float | np.ndarray]:
    """RelaxedIK's groove loss ``l = -exp(-(x - s)^d / (2 c^2)) + r (x - s)^g`` and dl/dx.

    The paper's form (Sec. IV-A) with n = 1; the defaults are its s = 0, c = 0.1, r = 10, d = g = 2.
    ``x`` is a scalar or an array (elementwise).
    """
    y = x - s
    bump = np.exp(-(y**d) / (2.0 * c * c))
    return -bump + r * y**g, bump * d * y ** (d - 1) / (2.0 * c * c) + r * g * y ** (g - 1)


def groove_curvature(x: np.ndarray, c: float = GROOVE_C, r: float = GROOVE_R) -> np.ndarray:
    """d²l/dx² of :func:`groove` with d = g = 2 at ``x``, floored at the quadratic part's 2r.

    The floor keeps the estimate positive past the bump's inflection (|x| > c)."""
    bump = np.exp(-(x**2) / (2.0 * c * c))
    return np.maximum(bump * (1.0 - x**2 / (c * c)) / (c * c), 0.0) + 2.0 * r


def groove_secant(x: float, c: float = GROOVE_C, r: float = GROOVE_R) -> float:
    """dl/dx / x of :func:`groove` with d = g = 2 at ``x``, its limit l''(0) at 0: the curvature of
    ``l(|e|)`` across the direction of e."""
    return float(np.exp(-(x**2) / (2.0 * c * c)) / (c * c) + 2.0 * r)


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


PRECONDITIONERS = ("gauss_newton", "scale", "none")
COLLISION_TOLERANCE = 1e-4  # m, NLopt's tolerance on the collision constraints
BAND_TOLERANCE = 1e-4  # m or rad, NLopt's tolerance on the hands' band
BOX_TOLERANCE = 1e-8  # rad, NLopt's tolerance on the joint box rows of a Chart (solve_frame says why)


@dataclass(frozen=True)
class SLSQPSettings(LimitSettings):
    """The loss terms, their weights, NLopt's stopping rule and the limits (:class:`LimitSettings`).

    The defaults are the paper's end-effector pose retargeting (Sec. IV-A, RelaxedIK's weights):
    w_p = 10, w_o = 9, w_v = 7, w_a = 2, w_j = 1 and w_i = 10 per criterion, divided by the
    number of criteria (Sec. V-A). :meth:`relative` gives the relative pose weights of Sec. V-B.

    Attributes:
        criteria: Human-likeness criteria added to the objective (paper names).
        scenario: ``pose``: every frame uses the weights below. ``relative``: the first frame tracks
            the TCP poses with the default pose weights instead of the relative pose (Sec. V-B).
        position, orientation: Weights of the TCP position (fPOS, m) and orientation (fORI, rad) losses.
        relative_position, relative_orientation: Weights of the relative pose losses (paper Eqs. 3-4).
        velocity, acceleration, jerk: Weights of RelaxedIK's minimum velocity, acceleration, jerk.
        criterion: Weight of the criteria together; each gets ``criterion / len(criteria)``.
        trunk: Weight of the extra (trunk) joints toward home
            (:class:`~hlik.criteria.joints.TrunkUpright`, h in rad^2; 0: none).
        gamma: Criterion name -> scaling gamma_i inside the groove (Table II; 1 where absent).
        position_gamma: gamma_p of the TCP and relative position losses (Sec. IV-A: 10).
        gradients: ``analytic`` (from the term Jacobians) or ``fd`` (forward differences, the paper's).
        ftol_rel: NLopt's relative tolerance on the objective (RelaxedIK's).
        max_eval: Objective evaluations per frame at most (RelaxedIK's 100).
        first_eval: Evaluations at most for the first frame, which starts from the mapped human pose.
        fd_step: Forward-difference step, rad (``fd`` only).
        self_collision: Keep the robot's collision geoms ``collision_margin`` apart (m), as NLopt
            inequality constraints ``margin - d_i(q) <= 0`` on the ``collision_pairs`` closest pairs
            within ``collision_detect`` (analytic gradients, :mod:`hlik.robot.collision`).
        precondition: How NLopt sees each frame (the module docstring says why): ``gauss_newton``
            in the variables x of :class:`Chart`, where the objective's Hessian is about the
            identity; ``scale``: divided by :func:`objective_scale`; ``none``: raw, as RelaxedIK.
        position_band, orientation_band: The hands' tolerance band, m and rad (0: none, the
            paper's weighted form): each hand's position and orientation error (relative pose
            errors in ``relative``) stays within it, or where a frame starts outside it, gets no
            worse than at the start (:class:`BandConstraint`); the criteria act inside it.
    """

    criteria: tuple[str, ...] = ()
    scenario: str = "pose"
    position: float = 10.0
    orientation: float = 9.0
    relative_position: float = 0.0
    relative_orientation: float = 0.0
    velocity: float = 7.0
    acceleration: float = 2.0
    jerk: float = 1.0
    criterion: float = 10.0
    trunk: float = 0.0
    gamma: Mapping[str, float] = field(default_factory=dict)
    position_gamma: float = 10.0
    gradients: str = "analytic"
    ftol_rel: float = 1e-6
    max_eval: int = 100
    first_eval: int = 1000
    fd_step: float = 1e-7
    self_collision: bool = True
    collision_margin: float = 0.01
    collision_detect: float = 0.10
    collision_pairs: int = 4
    precondition: str = "gauss_newton"
    position_band: float = 0.0
    orientation_band: float = 0.0

    def __post_init__(self):
        check_settings(
            self,
            at_least_zero=(
                "position",
                "orientation",
                "relative_position",
                "relative_orientation",
                "velocity",
                "acceleration",
                "jerk",
                "criterion",
                "trunk",
                "position_gamma",
                "collision_margin",
                "position_band",
                "orientation_band",
            ),
            positive=("fd_step", "collision_detect"),
            fractions=("ftol_rel",),
            counts=("max_eval", "first_eval", "collision_pairs"),
        )
        if self.gradients not in ("analytic", "fd"):
            raise SettingsError(f"SLSQPSettings.gradients must be 'analytic' or 'fd', got {self.gradients!r}")
        if self.precondition not in PRECONDITIONERS:
            known = ", ".join(PRECONDITIONERS)
            raise SettingsError(
                f"SLSQPSettings.precondition must be one of {known}, got {self.precondition!r}"
            )

    @classmethod
    def relative(cls, criteria: tuple[str, ...] = (), **changes) -> SLSQPSettings:
        """The paper's relative pose retargeting (Sec. V-B), ``changes`` applied on top.

        Relative position 3, relative orientation 15, velocity 40, acceleration 10, jerk 5, TCP
        position and orientation 0, and the criteria's weight scaled by 10 (100, divided by the
        number of criteria). The first frame tracks the TCP poses "as in Section V-A".
        """
        weights = dict(position=0.0, orientation=0.0, relative_position=3.0, relative_orientation=15.0)
        weights |= dict(velocity=40.0, acceleration=10.0, jerk=5.0, criterion=100.0)
        return cls(criteria=tuple(criteria), scenario="relative", **(weights | changes))


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

    The first frame of ``relative`` tracks the TCP poses "as in Section V-A": with the default
    (pose) weights, and the same criteria. The first frame leaves out the criteria of motion
    (``Criterion.motion``) and the minimum velocity, acceleration and jerk: it has no motion before
    it, and they would hold it at the pose it starts from (the mapped human's, on 2-Panda's Cut
    take 12 cm and 21° off the hand targets, which then took 30 frames to catch up).
    """
    if first and settings.scenario == "relative":
        pose = SLSQPSettings()
        settings = replace(
            pose, criteria=settings.criteria, gamma=settings.gamma, position_gamma=settings.position_gamma
        )
    if first:
        settings = replace(settings, velocity=0.0, acceleration=0.0, jerk=0.0)
    weighted: list[tuple[Term, float]] = [
        (fPOS(), settings.position),
        (fORI(), settings.orientation),
        (fPOS_off(), settings.relative_position),
        (fORI_off(), settings.relative_orientation),
        (Smoothness(VELOCITY, robot, "velocity"), settings.velocity),
        (Smoothness(ACCELERATION, robot, "acceleration"), settings.acceleration),
        (Smoothness(JERK, robot, "jerk"), settings.jerk),
    ]
    if robot.extra_joints:
        weighted.append((TrunkUpright(robot), settings.trunk))
    for name in settings.criteria:
        term = registry.criterion(name, robot, learned)
        if not (first and term.motion):
            weighted.append((term, settings.criterion / len(settings.criteria)))
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
        h, dh_de = term.part_metric(batch)  # (2m, P), (2m, P, m)
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

    Set the frame with :meth:`reset` before optimising. Keeps the configuration with the lowest
    finite objective NLopt asked for (:attr:`best`) and counts NLopt's evaluations.
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
        self.sites = _sites(loss.term.sites for loss in self.losses)
        self.value_sites = _sites(loss.term.value_sites for loss in self.losses)
        # a loss over both arms is one loss per arm, weighted half (Term.part_metric says why): h
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
        """Start a frame: forget the best configuration and the evaluation count. With ``q0`` (n,),
        NLopt's view of the frame is set up at ``q0`` as :attr:`precondition` says: :attr:`chart`
        (``gauss_newton``) and :attr:`scale`."""
        self.frame = frame
        self.best: np.ndarray | None = None
        self.best_value, self.evaluations, self.scale = np.inf, 0, 1.0
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
            h[piece], dh_dq[piece] = term.part_gradients_of(e, jac)
        else:
            h[piece.start], dh_dq[piece.start] = term.gradient_of(e, jac)

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
            h.append(term.part_metric(e)[0] if self.split[i] else [term.metric(e)[0]])
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
        if f < self.best_value:  # False for NaN
            self.best, self.best_value = q.copy(), f
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


def _sites(groups) -> tuple[int, ...]:
    return tuple(sorted({i for group in groups for i in group}))


def make_optimizer(robot: Robot, settings: SLSQPSettings) -> nlopt.opt:
    """NLopt's SLSQP over ``robot``'s joints; unlimited joints keep their infinite bounds."""
    opt = nlopt.opt(nlopt.LD_SLSQP, robot.dof)
    opt.set_lower_bounds(np.asarray(robot.lower, dtype=float))
    opt.set_upper_bounds(np.asarray(robot.upper, dtype=float))
    opt.set_ftol_rel(settings.ftol_rel)
    return opt


class CollisionConstraint:
    """NLopt's ``floor_i - d_i(q) <= 0`` for the k collision pairs nearest their floors (fewer:
    padded, met), in the variables of :attr:`chart` when it is set. A pair's floor is the margin,
    or the frame's braking distance where that is larger (:meth:`brake`)."""

    def __init__(self, robot: Robot, pairs: CollisionPairs, settings: SLSQPSettings):
        self.robot, self.pairs, self.settings = robot, pairs, settings
        self.data = mujoco.MjData(robot.model)
        self.bounds = DistanceBounds(pairs)
        self.chart: Chart | None = None
        self.floors = np.full(len(pairs), settings.collision_margin)
        self.detect: float | np.ndarray = settings.collision_detect

    def distances(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The pairs closer than :attr:`detect` at ``q`` (n,) (``collision_detect``, or per pair
        as far as :meth:`brake` looks): indices (k,), signed distances (k,) and their gradients
        (k, n)."""
        m = self.robot.model
        self.data.qpos[:] = q
        mujoco.mj_kinematics(m, self.data)
        mujoco.mj_comPos(m, self.data)
        return near_pairs(self.robot, self.data, self.pairs, self.detect, self.bounds)

    def brake(self, box: JointBox) -> None:
        """Set the floors for the frame of ``box``: the margin, raised to the braking distance of
        the pairs near at its start, each looked for as far as it needs
        (:func:`hlik.solvers.frames.collision_floors`)."""
        margin = self.settings.collision_margin
        found = collision_floors(self.robot, self.data, self.pairs, box, self.settings, self.bounds)
        if found is None:
            self.floors, self.detect = np.full(len(self.pairs), margin), self.settings.collision_detect
        else:
            self.floors, self.detect = np.maximum(margin, found[0]), found[1]

    def __call__(self, result: np.ndarray, x: np.ndarray, grad: np.ndarray) -> None:
        s = self.settings
        index, dist, jac = self.distances(x if self.chart is None else self.chart.q(x))
        slack = self.floors[index] - dist
        order = np.argsort(-slack)[: s.collision_pairs]
        result[:] = s.collision_margin - s.collision_detect  # absent pairs: far, met
        result[: len(order)] = slack[order]
        if grad.size:
            grad[:] = 0.0
            grad[: len(order)] = -jac[order] if self.chart is None else -jac[order] @ self.chart.T


class BandConstraint:
    """The hands' tolerance band as NLopt's ``h_p(q) - bound_p <= 0``, one row per arm (per part)
    of each target term that has a band: the error of hand p (m or rad) within the band or, in a
    frame where that cannot be met (a target out of reach, or one the limits let the hand only lag
    behind), no worse than at the frame's start (``bound_p = max(band, h_p(q_start))``), which is
    always feasible; the objective's tracking loss then pulls the hand in. In the variables of
    :attr:`chart` when set.
    """

    def __init__(self, robot: Robot, losses: Sequence[Loss], settings: SLSQPSettings):
        self.robot = robot
        self.terms = [loss.term for loss in losses if hand_band(loss.term, settings) > 0.0]
        self.bands = [hand_band(t, settings) for t in self.terms]
        self.sites = _sites(t.sites for t in self.terms)
        self.data = mujoco.MjData(robot.model)
        self.chart: Chart | None = None
        self.bound = np.zeros(0)
        self.frame: Sample | None = None

    def __len__(self) -> int:
        return sum(t.parts for t in self.terms)

    def errors(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Each hand's error (k,) of each banded term at ``q`` (n,) and its gradient (k, n)."""
        if self.frame is None:
            raise RuntimeError("BandConstraint.reset(frame, ...) must be called before evaluating")
        state = robot_state(self.robot, q, True, self.data, self.sites)
        parts = [t.part_gradients(state, self.frame) for t in self.terms]
        return np.concatenate([h for h, _ in parts]), np.vstack([g for _, g in parts])

    @property
    def band(self) -> np.ndarray:
        """(k,) each row's band."""
        return np.concatenate([np.full(t.parts, b) for t, b in zip(self.terms, self.bands)])

    def reset(self, frame: Sample, q_start: np.ndarray, chart: Chart | None, strict: bool) -> None:
        """Set the frame, its start ``q_start`` (n,) and the objective's chart; ``strict``: the
        bound is the band, else the band or the start's error where that is larger."""
        self.frame, self.chart = frame, chart
        self.bound = self.band if strict else np.maximum(self.band, self.errors(q_start)[0])

    def met(self, q: np.ndarray) -> bool:
        """Whether every hand is inside its band at ``q`` (n,), within NLopt's tolerance."""
        return bool(np.all(self.errors(q)[0] <= self.band + BAND_TOLERANCE))

    def __call__(self, result: np.ndarray, x: np.ndarray, grad: np.ndarray) -> None:
        h, dh_dq = self.errors(x if self.chart is None else self.chart.q(x))
        result[:] = h - self.bound
        if grad.size:
            grad[:] = dh_dq if self.chart is None else dh_dq @ self.chart.T


class BoxConstraint:
    """The joint box ``lower <= q(x) <= upper`` (its finite rows only) and the box's rows
    ``rows @ q(x) <= bound`` (the torque limits) as NLopt's linear ``A x <= b`` in a chart's
    variables; without a chart (x = q), the rows alone (NLopt takes the box as bounds)."""

    def __init__(self, chart: Chart | None, box: JointBox):
        rows, bound = box.step_rows(box.lower * 0.0 if chart is None else chart.origin)
        if chart is None:
            self.a, self.b = rows, bound
            return
        finite_upper, finite_lower = np.isfinite(box.upper), np.isfinite(box.lower)
        self.a = np.vstack([chart.T[finite_upper], -chart.T[finite_lower], rows @ chart.T])
        self.b = np.concatenate(
            [(box.upper - chart.origin)[finite_upper], (chart.origin - box.lower)[finite_lower], bound]
        )

    def __len__(self) -> int:
        return len(self.b)

    def __call__(self, result: np.ndarray, x: np.ndarray, grad: np.ndarray) -> None:
        result[:] = self.a @ x - self.b
        if grad.size:
            grad[:] = self.a


def solve_frame(
    opt: nlopt.opt,
    objective: Objective,
    frame: Sample,
    q0: np.ndarray,
    max_eval: int,
    box: JointBox,
    collision: CollisionConstraint | None = None,
    band: BandConstraint | None = None,
) -> tuple[np.ndarray, int]:
    """Minimise ``objective`` at ``frame`` from ``q0`` (n,) within ``box`` (and clear of
    ``collision``, the hands inside ``band``), in the objective's chart when it sets one. With a
    band, the frame is solved with the hands inside it first and, where that ends outside it (the
    band cannot be met from here), again with them no worse than at the start.

    Returns:
        (n,) the solution and NLopt's result code; on failure (negative code) the best finite
        configuration evaluated, else ``q0``.
    """
    if band is None or not len(band):
        return _solve_once(opt, objective, frame, q0, max_eval, box, collision, None)
    q, status = _solve_once(opt, objective, frame, q0, max_eval, box, collision, band, strict=True)
    if status > 0 and band.met(q):
        return q, status
    return _solve_once(opt, objective, frame, q0, max_eval, box, collision, band, strict=False)


def _solve_once(
    opt: nlopt.opt,
    objective: Objective,
    frame: Sample,
    q0: np.ndarray,
    max_eval: int,
    box: JointBox,
    collision: CollisionConstraint | None,
    band: BandConstraint | None,
    strict: bool = False,
) -> tuple[np.ndarray, int]:
    """One NLopt run of :func:`solve_frame`; ``strict``: the band as it is, else relaxed to the start."""
    objective.reset(frame, q0)
    chart = objective.chart
    opt.remove_inequality_constraints()
    if collision is not None:
        collision.chart = chart
        tolerance = np.full(collision.settings.collision_pairs, COLLISION_TOLERANCE)
        opt.add_inequality_mconstraint(collision, tolerance)
    if band is not None:
        band.reset(frame, q0, chart, strict)
        opt.add_inequality_mconstraint(band, np.full(len(band), BAND_TOLERANCE))
    if chart is None:
        opt.set_lower_bounds(box.lower)
        opt.set_upper_bounds(box.upper)
        x0 = q0
    else:
        opt.set_lower_bounds(np.full(len(q0), -np.inf))
        opt.set_upper_bounds(np.full(len(q0), np.inf))
        x0 = np.zeros(len(q0))
    bounds = BoxConstraint(chart, box)
    if len(bounds):
        # a joint starting on its limit starts on the row: with no tolerance, rounding in A x
        # made SLSQP's line search fail (ROUNDOFF_LIMITED) on 7 % of ARMAR-6's Cut frames
        opt.add_inequality_mconstraint(bounds, np.full(len(bounds), BOX_TOLERANCE))
    opt.set_min_objective(objective)
    opt.set_maxeval(max_eval)
    try:
        x = opt.optimize(x0)
        status = opt.last_optimize_result()
        q = x if chart is None else chart.q(x)
        if not (np.all(np.isfinite(q)) and np.isfinite(opt.last_optimum_value())):
            q, status = None, nlopt.FAILURE
    except tuple(NLOPT_ERRORS) as err:
        code = _nlopt_code(err)
        if code is None:
            raise
        q, status = None, code
    if q is None:
        q = objective.best if objective.best is not None else q0
    return np.asarray(q, dtype=float), int(status)


def solve(
    problem: Problem,
    settings: SLSQPSettings = SLSQPSettings(),
    learned: Learned | None = None,
    progress: Callable[[int], None] | None = None,
) -> SolverResult:
    """Retarget frame by frame.

    Diagnostics: ``iterations`` counts NLopt's objective evaluations (``fd``: each costs n + 1 FK
    passes), a frame has converged when NLopt stopped by its tolerance (not ``MAXEVAL_REACHED``) and
    failed when NLopt failed or returned a non-finite result; ``info["status"]`` (T,) holds NLopt's
    result codes.
    """
    robot = problem.robot
    if settings.criteria and learned is None:
        learned = learn(robot)
    s = settings
    objective = Objective(robot, build_losses(robot, s, learned), s.gradients, s.fd_step, s.precondition)
    first = Objective(robot, build_losses(robot, s, learned, True), s.gradients, s.fd_step, s.precondition)
    opt = make_optimizer(robot, settings)
    pairs = collision_pairs(robot) if settings.self_collision else None
    collision = CollisionConstraint(robot, pairs, settings) if pairs is not None and len(pairs) else None
    band, first_band = (BandConstraint(robot, o.losses, settings) for o in (objective, first))
    status = np.zeros(problem.n_frames, dtype=int)

    def solve_frame_k(k: int, frame: Sample, q: np.ndarray, box: JointBox) -> FrameResult:
        obj, max_eval, hands = (
            (first, settings.first_eval, first_band) if k == 0 else (objective, settings.max_eval, band)
        )
        if collision is not None:
            collision.brake(box)
        q, status[k] = solve_frame(opt, obj, frame, box.clip(q), max_eval, box, collision, hands)
        converged = status[k] > 0 and status[k] != nlopt.MAXEVAL_REACHED
        return FrameResult(box.clip(q), obj.evaluations, converged, status[k] < 0)

    result = track(problem, solve_frame_k, progress, MotionLimits.of(robot, settings))
    return replace(result, info=MappingProxyType({"status": status}))


def slsqp_solver(
    settings: SLSQPSettings = SLSQPSettings(),
    learned: Learned | None = None,
    progress: Callable[[int], None] | None = None,
) -> ConfiguredSolver:
    """The SLSQP solver (the paper's OPT) with the given settings, for :func:`hlik.retarget.retarget`."""
    return ConfiguredSolver("slsqp", solve, settings, learned, progress)
