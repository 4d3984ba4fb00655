"""SLSQP retargeting: the paper's OPT, RelaxedIK groove losses minimised per frame with NLopt.

Per frame, SLSQP minimises ``sum_i w_i l(gamma_i h_i(q))`` over the joint angles q within the joint
limits, where each h_i is the scalar cost of a term (:mod:`hlik.criteria`): the TCP pose or relative
pose errors, RelaxedIK's minimum velocity, acceleration and jerk toward the previous solutions, and
the chosen human-likeness criteria; l is the groove loss. A cost that is the mean over both arms
(fPOS, fORI, EEA, SOA_x, MAN^r, MJE) enters as one loss per arm, each with half the weight
(:func:`~hlik.solvers.gradients.part_metric`): the loss of the mean, l(|a| + |b|), has a kink
wherever one arm is on its target and the other is not, which at the optimum is everywhere, and
SLSQP crawled along it (ARMAR-6, Cut take: 65 evaluations a frame, 18 with the split). One
forward-kinematics pass per evaluation gives every h_i and, with ``gradients="analytic"``, its
exact gradient (:meth:`~hlik.criteria.base.Term.exact`); ``gradients="fd"`` uses forward
differences of the objective instead, as the paper and RelaxedIK do.
Frames are warm-started from the previous solution; where NLopt stops without a result, the frame
keeps the configuration it evaluated that missed the body's constraints least (the lowest
objective among equals; else the frame's start): a frame NLopt calls roundoff-limited is then
unconverged, any other failure is reported as failed. With ``preview_cost`` (off in the paper's
OPT) the take is solved twice, the second pass with one more loss toward a path within the
acceleration limits (:mod:`hlik.solvers.preview`, as the QP's look-ahead).

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

from hlik.solvers.settings import PRECONDITIONERS, SLSQPSettings
from hlik.solvers.slsqp.constraints import BandConstraint, BoxConstraint, CollisionConstraint
from hlik.solvers.slsqp.groove import groove, groove_curvature, groove_secant
from hlik.solvers.slsqp.objective import Chart, Loss, Objective, build_losses, loss_curvature, objective_scale
from hlik.solvers.slsqp.solver import make_optimizer, slsqp_solver, solve, solve_frame

__all__ = [
    "PRECONDITIONERS",
    "BandConstraint",
    "BoxConstraint",
    "Chart",
    "CollisionConstraint",
    "Loss",
    "Objective",
    "SLSQPSettings",
    "build_losses",
    "groove",
    "groove_curvature",
    "groove_secant",
    "loss_curvature",
    "make_optimizer",
    "objective_scale",
    "slsqp_solver",
    "solve",
    "solve_frame",
]
