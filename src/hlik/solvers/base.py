"""The solver interface: a :class:`~hlik.problem.problem.Problem` in, joint angles and per-frame
diagnostics out. Every solver (JM, JV, QP, SLSQP, a mink stack) is a :class:`Solver`."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, Protocol

import numpy as np

from hlik.problem.problem import Problem


@dataclass(frozen=True, eq=False)
class Diagnostics:
    """How each frame was solved; arrays (T,).

    Attributes:
        iterations: Steps (QP, JV, mink) or objective evaluations (SLSQP) spent on the frame (the
            first frame's over every start it was solved from, ``frames.track``).
        converged: The frame stopped by the solver's tolerance, not by its iteration cap (nor, in
            SLSQP, by NLopt's roundoff limit at a point that keeps the constraints).
        failed: The solver gave no usable solution; the frame keeps the best finite configuration
            it evaluated, or the previous frame's.
        solve_time: Wall-clock seconds spent on the frame.
    """

    iterations: np.ndarray
    converged: np.ndarray
    failed: np.ndarray
    solve_time: np.ndarray

    @classmethod
    def trivial(cls, n_frames: int, seconds: float = 0.0) -> Diagnostics:
        """Diagnostics of a closed-form solver (JM): one pass per frame, nothing to converge."""
        return cls(
            np.zeros(n_frames, dtype=int),
            np.ones(n_frames, dtype=bool),
            np.zeros(n_frames, dtype=bool),
            np.full(n_frames, seconds / max(n_frames, 1)),
        )

    @property
    def n_failed(self) -> int:
        return int(np.count_nonzero(self.failed))

    @property
    def n_unconverged(self) -> int:
        """Frames that ended without converging and without failing (the iteration cap; SLSQP's
        roundoff limit)."""
        return int(np.count_nonzero(~self.converged & ~self.failed))


@dataclass(frozen=True, eq=False)
class SolverResult:
    """Joint angles (T, n) in ``robot.joint_names`` order, diagnostics, and solver-specific extras
    (``info``, e.g. SLSQP's NLopt result codes)."""

    q: np.ndarray
    diagnostics: Diagnostics
    info: Mapping[str, Any] = field(default_factory=lambda: MappingProxyType({}))


class Solver(Protocol):
    """Anything with a ``name`` that turns a problem into a :class:`SolverResult`."""

    @property
    def name(self) -> str: ...

    def __call__(self, problem: Problem) -> SolverResult: ...


@dataclass(frozen=True)
class ConfiguredSolver:
    """A solver module's ``solve(problem, settings, progress)`` with its arguments bound. The
    learned pieces its criteria are built from come with the problem (:attr:`Problem.learned`).

    Attributes:
        name: Solver name (``jv``, ``qp``, ``slsqp``), recorded in the trajectory.
        solve: The module's ``solve`` function.
        settings: Its settings object.
        progress: Called with each frame index as it is solved.
    """

    name: str
    solve: Callable[..., SolverResult]
    settings: object
    progress: Callable[[int], None] | None = None

    @property
    def criteria(self) -> tuple[str, ...]:
        """The criteria the solver adds (what the problem must have learned pieces for)."""
        return tuple(getattr(self.settings, "criteria", ()))

    def __call__(self, problem: Problem) -> SolverResult:
        return self.solve(problem, self.settings, self.progress)
