"""What every criterion is: a residual e(q) with its Jacobian, and the cost h(e) the paper defines.

A :class:`Term` is anything the solvers stack (TCP targets, smoothness, the criteria); a
:class:`Criterion` is a term with the paper's constants (Table II gamma, Table III x0 and weight)
that :mod:`hlik.metrics` scores. Both work on F samples at once: ``residual`` (F, m),
``jacobian`` (F, m, n) and ``cost`` (F,) for configurations in a
:class:`~hlik.robot.state.RobotState` and what the criterion knows about those time samples in a
:class:`Sample`. ``hlik evaluate`` and the solvers' reported costs are the same :meth:`Term.cost`.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from hlik.robot.state import RobotState


@dataclass(frozen=True, eq=False)
class Sample:
    """What the terms know about F time samples besides the robot's configuration.

    Arrays are in the robot base frame, leading axis F (one row per time sample).

    Attributes:
        target_pos: (F, 2, 3) TCP target positions, m (arm 0 = left).
        target_rot: (F, 2, 3, 3) TCP target orientations.
        q_map: (F, n) the human pose mapped to the robot (unclipped; non-arm joints at home), rad.
        psi_mmm: (F, 2) the human's elbow elevation angles, rad.
        manip: (F, 2, 3, 3) the normalised human's manipulability, m².
        history: (F, 3, n) the three previous configurations, newest first, rad.
        dt: Sample period, s.
    """

    target_pos: np.ndarray
    target_rot: np.ndarray
    q_map: np.ndarray
    psi_mmm: np.ndarray
    manip: np.ndarray
    history: np.ndarray
    dt: float

    def __len__(self) -> int:
        return len(self.q_map)

    @classmethod
    def one(
        cls,
        target_pos: np.ndarray,
        target_rot: np.ndarray,
        q_map: np.ndarray,
        psi_mmm: np.ndarray,
        manip: np.ndarray,
        history: np.ndarray,
        dt: float,
    ) -> Sample:
        """The one-row sample of a single time: the arrays above without their leading axis."""

        def row(a: np.ndarray) -> np.ndarray:
            return np.asarray(a, dtype=float)[None]

        return cls(
            row(target_pos), row(target_rot), row(q_map), row(psi_mmm), row(manip), row(history), float(dt)
        )


class Term:
    """A residual e (F, m) with its Jacobian (F, m, n), and the scalar cost h (F,) of e.

    Subclasses implement :meth:`residual` and :meth:`jacobian` (or set ``constant_jacobian``) and,
    where h is not the mean of squares, :meth:`cost` and :meth:`cost_gradient` (and ``parts`` and
    ``part_form`` where h is a mean over the arms). Solvers read one sample through :meth:`__call__`
    (e, J) and :meth:`exact` (e, exact J); h and dh/dq of one sample, whole and per arm, follow in
    :mod:`hlik.solvers.gradients`. The weight a solver gives a term is the solver's, beside it.
    """

    name: str = "term"
    needs_sample: bool = True  # False: the residual depends on the configuration alone
    sites: tuple[int, ...] = (0, 1, 2, 3)  # site Jacobians the Jacobian reads (indices into SITES)
    value_sites: tuple[int, ...] = ()  # site Jacobians the residual itself reads
    constant_jacobian: np.ndarray | None = None  # (m, n) when J depends on neither q nor the sample
    # h is the mean over this many parts of e (the arms): h(e) = mean_p h(e_p) * parts, e_p keeping
    # part p's rows (:meth:`part_rows`) and zeros elsewhere
    parts: int = 1
    # how each part's cost depends on its rows, for a solver's curvature: "norm" (their Euclidean
    # norm), "squares" (mean of squares) or None (other, or Term's own mean of squares)
    part_form: str | None = None
    norm_scale: float = 1.0  # with part_form "norm": each part's cost is norm_scale |e_p|
    gradient_cap: float | None = None  # each dh/dq scaled down to this norm (:mod:`hlik.solvers.gradients`)
    # True where the residual measures the motion since the previous frames (MIS, MJE, the minimum
    # velocity, acceleration and jerk). The first frame has none (its history is itself), so the
    # solvers leave such terms out there (hlik.solvers.frames.first_frame_terms) rather than pull
    # the first pose toward the pose they start from.
    motion: ClassVar[bool] = False

    def part_rows(self, m: int) -> Sequence[np.ndarray]:
        """The rows of each part of a residual with ``m`` rows: :attr:`parts` equal slices."""
        return _equal_parts(m, self.parts)

    def residual(self, state: RobotState, sample: Sample) -> np.ndarray:
        """(F, m) residual at the F configurations of ``state``."""
        raise NotImplementedError

    def jacobian(self, state: RobotState, sample: Sample) -> np.ndarray:
        """(F, m, n) derivative of :meth:`residual` with respect to q."""
        if self.constant_jacobian is None:
            raise NotImplementedError
        return np.broadcast_to(self.constant_jacobian, (len(state.q), *self.constant_jacobian.shape))

    def cost(self, e: np.ndarray) -> np.ndarray:
        """(F,) the cost h of residuals (F, m): the mean of squares unless a criterion says otherwise."""
        return np.mean(e * e, axis=-1)

    def cost_gradient(self, e: np.ndarray) -> np.ndarray:
        """(F, m) dh/de of :meth:`cost`."""
        return 2.0 * e / max(e.shape[-1], 1)

    def __call__(self, state: RobotState, sample: Sample) -> tuple[np.ndarray, np.ndarray]:
        """Residual (m,) and Jacobian (m, n) of one sample (``state`` and ``sample`` with F = 1)."""
        jac = (
            self.constant_jacobian if self.constant_jacobian is not None else self.jacobian(state, sample)[0]
        )
        return self.residual(state, sample)[0], jac

    def metrics(self, e: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The cost h the solvers minimise (F,) of F residuals (F, m), and dh/de (F, m): :meth:`cost`
        unless the solvers minimise a stand-in (``Criterion.solver_form``)."""
        return self.cost(e), self.cost_gradient(e)

    def exact(self, state: RobotState, sample: Sample) -> tuple[np.ndarray, np.ndarray]:
        """Residual (m,) and its exact derivative d e / dq (m, n) of one sample; :meth:`__call__`'s
        Jacobian unless that one holds a prediction fixed (``Criterion.exact_jacobian``)."""
        return self(state, sample)


class Criterion(Term):
    """A human-likeness or functional criterion of the paper: a term with its constants.

    ``gamma`` is Table II's scaling weight in the solvers' costs, ``x0`` Table III's logistic
    mid-point of Eq. 1 and ``weight`` Table III's hierarchical weight of Eq. 2 (0 for the functional
    criteria, whose x0 depends on the scenario: :data:`hlik.criteria.unified.FUNCTIONAL_X0`).
    Instances are made per robot: ``Criterion(robot, piece)``, ``piece`` the attribute of
    :class:`~hlik.criteria.learned.Learned` named by :attr:`learned` (None for most criteria).
    """

    gamma: ClassVar[float] = 1.0
    x0: ClassVar[float] = 1.0
    weight: ClassVar[float] = 0.0
    functional: ClassVar[bool] = False
    # False where the Jacobian holds a configuration-dependent prediction fixed (a Gauss-Newton
    # step, not d residual / dq): EEA's Psi_human, Soechting's arm, fORI's first-order rotation.
    exact_jacobian: ClassVar[bool] = True
    # Set where exact_jacobian is False and a solver needs dh/dq: SLSQP then differentiates h
    # numerically and caps the gradient's norm at this value.
    numeric_gradient_cap: ClassVar[float | None] = None
    # Set where the solvers minimise another form than h (a smooth stand-in); it says which. They
    # still report h.
    solver_form: ClassVar[str | None] = None
    # The piece of :class:`~hlik.criteria.learned.Learned` the criterion is built from (``synergies``,
    # ``swivel``, ``scale``), fitted on a human corpus; None: it learns nothing.
    learned: ClassVar[str | None] = None

    def __init__(self, robot: object = None, piece: object = None):
        """Criteria that need neither the robot nor a learned piece take them and ignore them."""


@functools.cache
def _equal_parts(m: int, parts: int) -> tuple[np.ndarray, ...]:
    return tuple(np.array_split(np.arange(m), parts))


def block_norm_cost(e: np.ndarray, blocks: int) -> np.ndarray:
    """(F,) mean of the norms of ``blocks`` equal slices of each residual (F, m)."""
    return np.linalg.norm(e.reshape(len(e), blocks, -1), axis=-1).mean(axis=-1)


def block_norm_gradient(e: np.ndarray, blocks: int) -> np.ndarray:
    """(F, m) gradient of :func:`block_norm_cost` (zero where a slice is zero)."""
    parts = e.reshape(len(e), blocks, -1)
    norms = np.linalg.norm(parts, axis=-1, keepdims=True)
    return (parts / np.maximum(norms, 1e-12) / blocks).reshape(e.shape)
