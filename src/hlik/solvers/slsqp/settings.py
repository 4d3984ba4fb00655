"""The SLSQP solver's settings: the paper's OPT weights (Sec. IV-A, V-B) and NLopt's stopping rule."""

from __future__ import annotations

from dataclasses import dataclass

from hlik.solvers.base import check_settings
from hlik.solvers.settings import SolverSettings
from hlik.util.errors import SettingsError

PRECONDITIONERS = ("gauss_newton", "scale", "none")


@dataclass(frozen=True)
class SLSQPSettings(SolverSettings):
    """The loss terms, their weights, NLopt's stopping rule and the limits (:class:`LimitSettings`).

    The defaults are the paper's end-effector pose retargeting (Sec. IV-A, RelaxedIK's weights):
    w_p = 10, w_o = 9, w_v = 7, w_a = 2, w_j = 1 and w_i = 10 per criterion, divided by the
    number of criteria (Sec. V-A). :meth:`relative` gives the relative pose weights of Sec. V-B.

    Attributes:
        criteria: Human-likeness criteria added to the objective (paper names).
        scenario: ``pose``: every frame uses the weights below. ``relative``: the first frame tracks
            the TCP poses with the default pose weights instead of the relative pose (Sec. V-B).
        position_cost, orientation_cost: Weights of the TCP position (fPOS, m) and orientation (fORI,
            rad) losses.
        relative_position_cost, relative_orientation_cost: Weights of the relative pose losses
            (paper Eqs. 3-4).
        velocity_cost, acceleration_cost, jerk_cost: Weights of RelaxedIK's minimum velocity,
            acceleration, jerk.
        criterion_cost: Weight of the criteria together; each gets ``criterion_cost / len(criteria)``.
        trunk_cost: Weight of the extra (trunk) joints toward home
            (:class:`~hlik.criteria.joints.TrunkUpright`, h in rad^2; 0: none).
        elbow_cost: Weight of the elbows behind the shoulders' frontal plane by more than
            ``elbow_allowance`` (m) (:class:`~hlik.criteria.elbows.ElbowsAhead`, h in m^2; 0: none).
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

    position_cost: float = 10.0
    orientation_cost: float = 9.0
    relative_position_cost: float = 0.0
    relative_orientation_cost: float = 0.0
    velocity_cost: float = 7.0
    acceleration_cost: float = 2.0
    jerk_cost: float = 1.0
    criterion_cost: float = 10.0
    trunk_cost: float = 0.0
    elbow_cost: float = 0.0
    elbow_allowance: float = 0.02
    position_gamma: float = 10.0
    gradients: str = "analytic"
    ftol_rel: float = 1e-6
    max_eval: int = 100
    first_eval: int = 1000
    fd_step: float = 1e-7
    collision_pairs: int = 4
    precondition: str = "gauss_newton"
    position_band: float = 0.0
    orientation_band: float = 0.0

    def __post_init__(self):
        check_settings(
            self,
            at_least_zero=("position_gamma", "position_band", "orientation_band", "elbow_allowance"),
            positive=("fd_step",),
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
        weights = dict(
            position_cost=0.0,
            orientation_cost=0.0,
            relative_position_cost=3.0,
            relative_orientation_cost=15.0,
        )
        weights |= dict(velocity_cost=40.0, acceleration_cost=10.0, jerk_cost=5.0, criterion_cost=100.0)
        return cls(criteria=tuple(criteria), scenario="relative", **(weights | changes))
