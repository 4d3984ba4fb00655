"""What every optimising solver is told (:class:`SolverSettings`); what each solver is and can do
is its :class:`~hlik.solvers.catalog.SolverSpec`."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

from hlik.solvers.limits import LimitSettings


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
