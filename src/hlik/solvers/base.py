"""The solver interface: a :class:`~hlik.problem.problem.Problem` in, joint angles and per-frame
diagnostics out. Every solver (JM, JV, QP, SLSQP, a mink stack) is a :class:`Solver`."""

from __future__ import annotations

import dataclasses
import math
import numbers
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, Protocol

import numpy as np

from hlik.problem.problem import Problem
from hlik.solvers.bounds import MAX_COUNT, MAX_WEIGHT
from hlik.util.errors import SettingsError


@dataclass(frozen=True, eq=False)
class Diagnostics:
    """How each frame was solved; arrays (T,).

    Attributes:
        iterations: Steps (QP, JV, mink) or objective evaluations (SLSQP) spent on the frame.
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


def check_settings(
    settings: object,
    *,
    at_least_zero: Sequence[str] = (),
    positive: Sequence[str] = (),
    at_most_zero: Sequence[str] = (),
    fractions: Sequence[str] = (),
    counts: Sequence[str] = (),
) -> None:
    """Check a solver's settings dataclass in its ``__post_init__``, so that the Python API refuses
    what a stack file would: every listed field a finite number ``>= 0`` (``at_least_zero``),
    ``> 0`` (``positive``), ``<= 0`` (``at_most_zero``), in (0, 1] (``fractions``) or a whole
    number in [1, :data:`MAX_COUNT`] (``counts``); the ``scenario``, the ``gamma`` table (criterion
    -> finite number ``>= 0``) and, where present, ``collision_detect > collision_margin``. Every
    weight (a field named ``<what>_cost``) is in [0, :data:`MAX_WEIGHT`], ``collision_margin``
    ``>= 0`` and ``collision_detect > 0`` without being listed.

    Raises:
        SettingsError: ``"<Class>.<field> must be ..., got <value>"`` for the first bad field
            (:mod:`hlik.solvers.stack_file` turns it into ``"<file>: [<solver>] <field> ..."``).
    """
    owner = type(settings).__name__
    weights = tuple(f.name for f in dataclasses.fields(settings) if f.name.endswith("_cost"))  # type: ignore[arg-type]
    at_least_zero = (*weights, *at_least_zero)
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
    for keys, rule, holds in rules:
        for key in keys:
            value = getattr(settings, key)
            if not (_is_real(value) and math.isfinite(value) and holds(value)):
                fail(key, rule)
    for key in weights:  # a weight of 1e300 overflows the objective's squares
        if getattr(settings, key) > MAX_WEIGHT:
            fail(key, f"a finite number in [0, {MAX_WEIGHT:g}]")
    for key in counts:
        value = getattr(settings, key)
        integral = isinstance(value, numbers.Integral) and not isinstance(value, bool)
        if not (integral and 1 <= int(value) <= MAX_COUNT):
            fail(key, f"a whole number in [1, {MAX_COUNT}]")
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
