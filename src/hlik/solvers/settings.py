"""What each solver is told: the limits every solver keeps (:class:`LimitSettings`), the fields the
optimising solvers share (:class:`SolverSettings`), each solver's own settings (:class:`JVSettings`,
:class:`QPSettings`, :class:`SLSQPSettings`, :class:`MinkSettings`) and their check
(:func:`check_settings`). What each solver is and can do is its
:class:`~hlik.solvers.catalog.SolverSpec`.

Light on purpose: a stack file's values are checked against these classes before MuJoCo, mink or
NLopt load, so a bad value is answered at once (the solvers import them from here).
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType

from hlik.solvers.bounds import MAX_COUNT, MAX_WEIGHT
from hlik.util.errors import SettingsError

# 3 deg: a controller's usual software margin, and ARMAR-III's smallest range (Wrist 1, 53 deg) keeps
# nine tenths of its travel
STOP_MARGIN = math.radians(3.0)


@dataclass(frozen=True)
class LimitSettings:
    """What the solvers keep besides the position and speed limits (every solver's settings have
    these fields; ``[qp]``, ``[jv]``, ``[slsqp]`` in a stack file set them).

    Attributes:
        stop_margin: Margin kept from every position stop, rad (at most a fifth of a joint's range).
        acceleration_limits: Keep the robot's ``[acceleration_limits]`` and ``[jerk_limits]``, and brake
            before the stops.
        torque_limits: Keep the joint torques within ``torque_fraction`` of ``[effort_limits]``.
        torque_fraction: Share of the effort limit the linearised torque rows allow (the rows
            take the Coriolis terms at the previous frame's speed).
    """

    stop_margin: float = STOP_MARGIN
    acceleration_limits: bool = True
    torque_limits: bool = True
    torque_fraction: float = 0.9


@dataclass(frozen=True)
class SolverSettings(LimitSettings):
    """The fields the QP, JV and SLSQP settings share (the limits of :class:`LimitSettings` too);
    a stack file's ``[qp]``, ``[jv]`` and ``[slsqp]`` tables set them under the same names.

    Attributes:
        criteria: Human-likeness criteria the solver adds (paper names).
        scenario: ``pose`` tracks both TCP poses; ``relative`` the relative pose of the hands
            (paper Eqs. 3-4), the TCP poses only at the first frame (Sec. V-B).
        gamma: Criterion name -> scaling weight gamma_i (Table II where absent, or the solver's).
        criterion_cost: Weight of the criteria together; each gets ``gamma_i * criterion_cost /
            len(criteria)`` (divided by their number as in the paper, Sec. V).
        self_collision: Keep every pair of the robot's collision geoms ``collision_margin`` apart
            (m), acting on pairs closer than ``collision_detect`` (m).
    """

    criteria: tuple[str, ...] = ()
    scenario: str = "pose"
    gamma: Mapping[str, float] = field(default_factory=dict)
    criterion_cost: float = 1.0
    self_collision: bool = True
    collision_margin: float = 0.01
    collision_detect: float = 0.10


# the QP backend hlik depends on (qpsolvers' other installed solvers by name)
DEFAULT_BACKEND = "daqp"

# HJA_r's Table II gamma (2) doubled for the QP: beside SYN (gamma 6) it barely acted, and SYN +
# HJA_r raised 2-Panda's m_hl by 0.042; at 4 by 0.051 (README, quality table), tracking within 2 cm.
GAMMA: Mapping[str, float] = MappingProxyType({"HJA_r": 4.0})


@dataclass(frozen=True)
class QPSettings(SolverSettings):
    """The task stack, the stopping rule and the limits (:class:`LimitSettings`: stop margin,
    acceleration and torque limits).

    Attributes:
        criteria: Human-likeness criteria added to the stack (paper names).
        scenario: ``pose`` tracks both TCP poses; ``relative`` tracks the relative pose of the hands
            (paper Eqs. 3-4) and the TCP poses only at the first frame (Sec. V-B).
        position_cost, orientation_cost: TCP pose term weights, per metre and per radian.
        relative_position_cost, relative_orientation_cost: Relative pose weights (``relative``).
        gamma: Criterion name -> scaling weight, overriding the criterion's Table II gamma
            (:data:`GAMMA`: HJA_r's doubled).
        criterion_cost: Objective weight of the criteria: criterion i adds
            ``gamma_i * criterion_cost / len(criteria) * ||e_i||^2`` (divided by the number of
            criteria as in the paper; its least-squares cost is the square root).
        velocity_cost, acceleration_cost, jerk_cost: Weights of the smoothness terms.
        trunk_cost: Weight per rad of the extra (trunk) joints toward home
            (:class:`~hlik.criteria.joints.TrunkUpright`; 0: none; robots without them: no term).
        elbow_cost: Weight per metre of an elbow behind the shoulders' frontal plane by more than
            ``elbow_allowance`` (m) (:class:`~hlik.criteria.elbows.ElbowsAhead`; 0: none).
        preview_cost: Weight per rad toward the look-ahead path (:mod:`hlik.solvers.preview`:
            the take retargeted without acceleration and torque limits, then the nearest path that
            keeps them, started early; 0: none, one pass). Above 0 the take is solved twice.
        preview_hands_first: The look-ahead's first pass holds the hands first (as
            ``hands_first``), so its path follows the hands and the second, weighted pass shapes
            the arm toward it; False: the first pass is weighted as the second. ``hands_first``
            implies it.
        damping: Levenberg-Marquardt damping of every step.
        error_damping: The hand targets' own damping, growing with their error: each hand term
            adds ``error_damping * |w e|^2`` (its weighted squared error) to the step's Hessian
            (mink's ``lm_damping``; Sugihara 2011's lambda = E). A target out of reach then damps
            its steps instead of overshooting between them (0: none).
        max_iter: QP steps per frame at most (the first frame gets ten times more).
        tol: A frame has converged when no joint moves more than this in a step, rad.
        max_step: Bound on any joint's change in one step, rad.
        solver: qpsolvers backend.
        position_band, orientation_band: The hands' tolerance band, m and rad (0: none, the
            paper's weighted form): each target term's error after a step stays within it,
            component by component within band / sqrt(3) (so its norm within band), as linear
            inequalities below the body's; where no step can meet them, as near as the body's rows
            let a step come (:func:`~hlik.solvers.frames.nearest_band`); the criteria act inside.
        hands_first: A strict priority of the hands over the posture: each step first solves the
            hands, smoothness and look-ahead alone, then adds the criteria, trunk and elbow terms
            in the hands' null space (``MinkSolver``'s ``posture``); False: one weighted QP.
        self_collision: Keep every pair of the robot's collision geoms ``collision_margin`` apart
            (m), as linear inequalities on the step from their signed distances and gradients
            (the velocity damper of mink's ``CollisionAvoidanceLimit``: a pair closer than
            ``collision_detect`` may approach by at most ``collision_gain`` of its distance to the
            margin per step).
    """

    gamma: Mapping[str, float] = field(default_factory=lambda: GAMMA)
    # hands first (issue 28; were 10 and 1): the criteria had bought m_hl by turning the hands
    # (tasks/ee_pose.toml and README "Hands first" have the measurements)
    position_cost: float = 30.0
    orientation_cost: float = 2.0
    relative_position_cost: float = 10.0
    relative_orientation_cost: float = 2.0
    criterion_cost: float = 0.05
    velocity_cost: float = 0.02
    acceleration_cost: float = 0.01
    jerk_cost: float = 0.005
    # ARMAR-III's hip upright (issue 28; tasks/ee_pose.toml and README "Trunk upright" say why 2)
    trunk_cost: float = 2.0
    # 2-Panda's elbows out from behind its back (issue 28; tasks/ee_pose.toml says why 11)
    elbow_cost: float = 11.0
    elbow_allowance: float = 0.02
    position_band: float = 0.0
    orientation_band: float = 0.0
    hands_first: bool = False
    # the look-ahead (issue 28; tasks/ee_pose.toml has the measurements)
    preview_cost: float = 3.0
    # off but on 2-Panda (tasks/ee_pose.toml, README "A strict priority" have the measurements)
    preview_hands_first: bool = False
    damping: float = 1e-6
    # opt-in: it settles the chatter at targets out of reach, and slows a hand catching up with a
    # reachable one (README "What the limits leave" has the measurements)
    error_damping: float = 0.0
    max_iter: int = 20
    tol: float = 1e-4
    max_step: float = 0.2
    solver: str = DEFAULT_BACKEND
    collision_gain: float = 0.5

    @property
    def priority(self) -> str:
        """How the hands rank against the posture: ``hands_first`` (every step),
        ``preview_hands_first`` (the look-ahead's first pass only, so only with a pull) or
        ``weighted``."""
        if self.hands_first:
            return "hands_first"
        if self.preview_hands_first and self.preview_cost > 0:
            return "preview_hands_first"
        return "weighted"

    def __post_init__(self):
        check_settings(
            self,
            at_least_zero=(
                "position_band",
                "orientation_band",
                "damping",
                "error_damping",
                "elbow_allowance",
            ),
            positive=("tol", "max_step"),
            fractions=("collision_gain",),
            counts=("max_iter",),
        )
        if self.solver != DEFAULT_BACKEND:  # daqp is a dependency; only another loads qpsolvers
            from hlik.solvers.qp_backend import qp_backends

            if self.solver not in qp_backends():
                raise SettingsError(
                    f"QPSettings.solver {self.solver!r} is not an installed QP solver; "
                    f"choose one of: {', '.join(qp_backends())}"
                )


@dataclass(frozen=True)
class JVSettings(SolverSettings):
    """The controller's gains, the stopping rule and the limits (:class:`LimitSettings`).

    Attributes:
        criteria: Human-likeness criteria of the null-space task (paper names; the paper leaves MJE
            out of JV).
        scenario: ``pose`` tracks both TCP poses; ``relative`` tracks the relative pose of the hands
            (paper Eqs. 3-4) and the TCP poses only at the first frame (Sec. V-B), as the QP does.
        gamma: Criterion name -> scaling weight gamma_i (Table II; 1 where absent).
        criterion_cost: w_i = criterion_cost * gamma_i, divided by the number of criteria (paper
            Sec. V: 0.1).
        jla_gamma: gamma of Chan & Dubey's H in the null-space cost (paper Sec. V: 4), so
            w_H = criterion_cost * jla_gamma, not divided (H is no human-likeness criterion); 0 drops H.
        step: Gain on the Cartesian error, x_dot = -step * e (Simox CompositeDiffIK ``stepSize``).
        k: Null-space gain; k < 0 descends (paper Sec. V, Chan & Dubey Eq. 10).
        max_null: Bound on the largest joint change of the null-space step, rad (paper:
            max|dH| <= 0.2); it halves whenever the null-space step reverses and doubles from
            one frame to the next, up to this (and no lower than a thousandth of it).
        max_step: Bound on the largest joint change of a whole step, scaled down uniformly, rad
            (Simox CompositeDiffIK ``maxJointAngleStep``).
        damping: Least lambda of the damped least-norm solution (m, as the position rows set the
            Jacobian's scale). It keeps singular targets bounded.
        error_damping: lambda² = damping² + |e|² (Sugihara 2011): large errors, i.e. targets out of
            reach, get strong damping, small ones the least. False: lambda = damping throughout.
        orientation_cost: Orientation rows (rad) relative to position rows (m) in the primary task;
            it matters only where the targets conflict or are damped. 0.2 is the QP's 2 / 10.
        rcond: Singular values of J below rcond times the largest count as null space.
        max_iter: Steps per frame at most (paper: 100; the first frame gets ten times more).
        tol: A frame has converged when no joint moved more than this in a step, rad.
        reached_position, reached_orientation: With both above 0, a frame also ends, after its
            first step, once every target is within this distance (m) and angle (rad) of the
            robot's: the paper's "until reaching target poses". ``paper_opt.toml`` sets Simox
            CompositeDiffIK's thresholds (``Target.maxPosError`` 10 mm, ``maxOriError`` 0.05 rad);
            the default 0 steps on until ``tol`` (hands on target to well under a millimetre).
        self_collision: Keep every pair of the robot's collision geoms ``collision_margin`` apart
            (m) with the QP's velocity damper (a pair closer than ``collision_detect`` may approach
            by at most ``collision_gain`` of its distance to the margin per step), as the task of
            highest priority: a step that breaks it is replaced (:func:`avoiding_least_norm`).
    """

    criterion_cost: float = 0.1
    jla_gamma: float = 4.0
    step: float = 0.5
    k: float = -0.5
    max_null: float = 0.2
    max_step: float = 0.2
    damping: float = 5e-3
    error_damping: bool = True
    orientation_cost: float = 0.2
    rcond: float = 1e-6
    max_iter: int = 100
    tol: float = 1e-4
    reached_position: float = 0.0
    reached_orientation: float = 0.0
    collision_gain: float = 0.5

    def __post_init__(self):
        check_settings(
            self,
            at_least_zero=("jla_gamma", "damping", "reached_position", "reached_orientation"),
            positive=("step", "max_null", "max_step", "tol"),
            at_most_zero=("k",),  # k > 0 would climb the null-space cost
            fractions=("rcond", "collision_gain"),
            counts=("max_iter",),
        )


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
        preview_cost: Weight of the loss toward the look-ahead path (:mod:`hlik.solvers.preview`,
            as the QP's ``preview_cost``; a :class:`~hlik.solvers.preview.PathTerm`, h in rad);
            0: none, one pass, the paper's OPT. Above 0 the take is solved twice.
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
    preview_cost: float = 0.0

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


@dataclass(frozen=True)
class MinkSettings(QPSettings):
    """The QP's settings (:class:`~hlik.solvers.qp.QPSettings`) and the stack's own mink objects.

    Attributes:
        tasks: mink tasks added beside hlik's, each ``{type = "<mink class>", <parameters>}``.
        limits: mink limits added beside hlik's frame box and collision rows, alike.
    """

    tasks: tuple[Mapping[str, object], ...] = ()
    limits: tuple[Mapping[str, object], ...] = ()

    def __post_init__(self):
        super().__post_init__()
        if self.tasks or self.limits:  # checked against mink's classes, so mink loads only for them
            from hlik.solvers.mink_specs import check_specs

            object.__setattr__(self, "tasks", check_specs(self.tasks, "tasks"))
            object.__setattr__(self, "limits", check_specs(self.limits, "limits"))


def check_settings(
    settings: object,
    *,
    at_least_zero: Sequence[str] = (),
    positive: Sequence[str] = (),
    at_most_zero: Sequence[str] = (),
    fractions: Sequence[str] = (),
    counts: Sequence[str] = (),
    weights: Sequence[str] = (),
) -> None:
    """Check a solver's settings dataclass in its ``__post_init__``, so that the Python API refuses
    what a stack file would: every listed field a finite number ``>= 0`` (``at_least_zero``),
    ``> 0`` (``positive``), ``<= 0`` (``at_most_zero``), in (0, 1] (``fractions``) or a whole
    number in [1, :data:`MAX_COUNT`] (``counts``); the ``scenario``, the ``gamma`` table (criterion
    -> finite number ``>= 0``) and, where present, ``collision_detect > collision_margin``. Every
    weight (a field named ``<what>_cost``) is in [0, :data:`MAX_WEIGHT`], ``collision_margin``
    ``>= 0`` and ``collision_detect > 0`` without being listed (``weights``: other fields bounded as
    the weights), and every switch (a ``bool``
    field) True or False.

    Raises:
        SettingsError: ``"<Class>.<field> must be ..., got <value>"`` for the first bad field
            (:mod:`hlik.solvers.stack_file` turns it into ``"<file>: [<solver>] <field> ..."``).
    """
    owner = type(settings).__name__
    weights = (*weights, *(f.name for f in dataclasses.fields(settings) if f.name.endswith("_cost")))  # type: ignore[arg-type]
    if hasattr(settings, "collision_margin"):  # SolverSettings
        at_least_zero, positive = (*at_least_zero, "collision_margin"), (*positive, "collision_detect")
    if hasattr(settings, "stop_margin"):  # every solver's LimitSettings
        at_least_zero, fractions = (*at_least_zero, "stop_margin"), (*fractions, "torque_fraction")

    def fail(key: str, rule: str) -> None:
        value = getattr(settings, key)
        shown = str(value) if _is_real(value) else repr(value)
        raise SettingsError(f"{owner}.{key} must be {rule}, got {shown}")

    rules = (
        (at_least_zero, "a finite number >= 0", lambda v: v >= 0),
        (positive, "a finite number > 0", lambda v: v > 0),
        (at_most_zero, "a finite number <= 0", lambda v: v <= 0),
        (fractions, "a number in (0, 1]", lambda v: 0 < v <= 1),
    )
    # a weight of 1e300 overflows the objective's squares: one rule, both bounds in its message
    weight_rule = (weights, f"a finite number in [0, {MAX_WEIGHT:g}]", lambda v: 0 <= v <= MAX_WEIGHT)
    for keys, rule, holds in (weight_rule, *rules):
        for key in keys:
            value = getattr(settings, key)
            if not (_is_real(value) and math.isfinite(value) and holds(value)):
                fail(key, rule)
    for key in counts:
        value = getattr(settings, key)
        integral = isinstance(value, numbers.Integral) and not isinstance(value, bool)
        if not (integral and 1 <= int(value) <= MAX_COUNT):
            fail(key, f"a whole number in [1, {MAX_COUNT}]")
    for f in dataclasses.fields(settings):  # type: ignore[arg-type]
        # a switch given "no" or 0 from Python was taken as on or off by its truth
        if f.type in ("bool", bool) and not isinstance(getattr(settings, f.name), bool):
            fail(f.name, "true or false")
    _check_choices(settings, owner)


def _check_choices(settings: object, owner: str) -> None:
    """The parts of :func:`check_settings` that are not one number: scenario, gamma table and the
    collision distances' order."""
    scenario = getattr(settings, "scenario", "pose")
    if scenario not in ("pose", "relative"):
        raise SettingsError(f"{owner}.scenario must be 'pose' or 'relative', got {scenario!r}")
    gamma = getattr(settings, "gamma", {})
    if not isinstance(gamma, Mapping):
        raise SettingsError(f"{owner}.gamma must be a mapping of criterion name -> number, got {gamma!r}")
    for name, value in gamma.items():
        if not (_is_real(value) and math.isfinite(value) and 0 <= value <= MAX_WEIGHT):
            shown = str(value) if _is_real(value) else repr(value)
            rule = f"a finite number in [0, {MAX_WEIGHT:g}]"  # a gamma of 1e300 failed every frame
            raise SettingsError(f"{owner}.gamma {name} must be {rule}, got {shown}")
    margin, detect = getattr(settings, "collision_margin", 0.0), getattr(settings, "collision_detect", 1.0)
    if detect <= margin:  # both checked above: the damper acts between the two distances
        raise SettingsError(
            f"{owner}.collision_detect must be larger than collision_margin ({margin}), got {detect}"
        )


def _is_real(value: object) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


@dataclass(frozen=True)
class WholeTakeSettings:
    """How :mod:`hlik.solvers.whole_take` optimises the whole take; SI units.

    Attributes:
        iterations: Linearisations (QP solves) at most.
        position_band: Each hand within this of its target per axis, m (or as far as the run left it).
        orientation_band: A hand turned less than this from its target costs nothing, rad; beyond
            it, the square of the angle beyond.
        pull: Weight per rad^2 of each joint's distance to the frame-by-frame solution, against the
            hands' orientation errors (rad^2).
        trunk_pull: The same pull on the extra (trunk) joints (ARMAR-III's hip), which would else
            turn the hands with the body.
        position_cost: Weight per m^2 of each hand's distance from its target (within the band's
            corner; linear beyond it: the hands as near as the rest allows).
        smoothness: Weight of the squared second differences of the change made to the run
            (rad^2 per rad^2), so that the change adds no jerk.
        trust_region: The first iteration's largest joint step, rad (grown 1.5x on a kept step to
            ``max_trust_region``, halved on a rejected one).
        max_trust_region: Largest joint step of an iteration, rad.
        stop_margin: Kept from every position stop, rad (at most a fifth of a joint's range).
        headroom: Share of the speed, acceleration and jerk limits the rows allow.
        torque_fraction: Share of the effort limits the linearised torque rows allow.
        torque_watch: Only torques above this share of their efforts get rows (fewer rows, a faster
            QP; a step that takes another over its effort is refused).
        collision_margin: Least distance between collision geoms, m.
        collision_detect: Pairs closer than this at the linearisation get a row, m.
        min_trust_region: Stop once the trust region is below this, rad.
        tolerance: Stop once a kept step lowers the merit by less than this share of it.
        criteria: The human-likeness criteria the solver added (paper names), here evaluated
            again: each of one frame's pose weighs ``gamma_i * criterion_cost / len(criteria)``
            per squared residual.
        gamma: Criterion name -> gamma_i, over Table II's (the solver's own).
        criterion_cost: The criteria's weight against the hands' orientation beyond the band
            (rad^2).
        trunk_upright: Weight per rad^2 of the extra (trunk) joints' distance from home
            (:class:`~hlik.criteria.joints.TrunkUpright`, the QP's ``trunk_cost`` term): the trunk
            as upright as the hands allow (0: none).
    """

    iterations: int = 20
    position_band: float = 0.003
    orientation_band: float = math.radians(2.0)
    pull: float = 0.03
    trunk_pull: float = 1.0
    position_cost: float = 100.0
    smoothness: float = 1e4
    trust_region: float = math.radians(3.0)
    max_trust_region: float = math.radians(30.0)
    stop_margin: float = STOP_MARGIN
    headroom: float = 0.99
    torque_fraction: float = 0.9
    torque_watch: float = 0.5
    collision_margin: float = 0.01
    collision_detect: float = 0.05
    min_trust_region: float = 1e-4
    tolerance: float = 1e-4
    criteria: tuple[str, ...] = ()
    gamma: Mapping[str, float] = field(default_factory=dict)
    criterion_cost: float = 0.0125
    trunk_upright: float = 0.0

    def __post_init__(self):
        check_settings(
            self,
            at_least_zero=("position_band", "orientation_band"),
            positive=("trust_region", "max_trust_region", "min_trust_region", "tolerance"),
            fractions=("headroom", "torque_watch"),
            counts=("iterations",),
            weights=("pull", "trunk_pull", "smoothness", "trunk_upright"),
        )
        if not self.min_trust_region <= self.trust_region <= self.max_trust_region:
            raise SettingsError(
                "WholeTakeSettings.trust_region must lie in [min_trust_region, max_trust_region] "
                f"({self.min_trust_region}, {self.max_trust_region}), got {self.trust_region}"
            )


# what the whole-take stage keeps of the solver it follows
SOLVERS_OWN = ("stop_margin", "torque_fraction", "collision_margin", "criteria", "gamma")


def settings_for(solver_settings: object | None, stage: WholeTakeSettings | None = None) -> WholeTakeSettings:
    """The stage's settings ``stage`` (a stack's ``[whole_take]``; the defaults if None) keeping a
    solver's limits and criteria (:data:`SOLVERS_OWN`: ``stop_margin``, ``torque_fraction``,
    ``collision_margin``, ``criteria``, ``gamma``) where its settings have them (JV, QP, SLSQP,
    mink). A solver's margin at or beyond the stage's ``collision_detect`` moves it out with the
    margin: the pairs watched that far beyond the margin as before."""
    stage = stage or WholeTakeSettings()
    own = {name: getattr(solver_settings, name) for name in SOLVERS_OWN if hasattr(solver_settings, name)}
    margin = own.get("collision_margin", stage.collision_margin)
    if stage.collision_detect <= margin:
        own["collision_detect"] = margin + max(stage.collision_detect - stage.collision_margin, 0.01)
    return dataclasses.replace(stage, **own)
