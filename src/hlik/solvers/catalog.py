"""The solvers hlik knows by name, and what each can do (:class:`SolverSpec`), so that code outside
the solvers asks a solver's spec instead of testing its name.

The catalogue names each solver's module and imports it on first use: checking a solver name (the
CLI does before anything heavy loads) costs no import of MuJoCo, mink or NLopt.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from importlib import import_module
from types import MappingProxyType
from typing import TYPE_CHECKING

from hlik.util.errors import SettingsError, UnknownNameError
from hlik.util.tomlfile import did_you_mean

if TYPE_CHECKING:
    from hlik.solvers.base import Solver
    from hlik.solvers.settings import SolverSettings


@dataclass(frozen=True)
class SolverSpec:
    """One solver hlik knows by name.

    Attributes:
        name: ``jm``, ``jv``, ``qp``, ``slsqp``, ``mink``.
        module: The module holding its factory ``<name>_solver(settings, progress) -> Solver``.
        settings_class: Its settings class's name (a :class:`SolverSettings`) in
            ``settings_module``, None where it takes none.
        takes_criteria: It can add human-likeness criteria.
        tracks_targets: It follows the hand targets (JM maps the joint angles instead: it is not
            warned about lagging hands or speeds it never promised to keep).
        settings_module: The module holding the settings class: a light one, since a stack file's
            values are checked against it before any solver loads (:mod:`hlik.solvers.settings`).
    """

    name: str
    module: str
    settings_class: str | None
    takes_criteria: bool = True
    tracks_targets: bool = True
    settings_module: str = "hlik.solvers.settings"

    @property
    def factory(self) -> Callable[..., Solver]:
        """``factory(settings, progress) -> Solver`` (imports the solver's module).

        Raises:
            UnknownNameError: a solver hlik does not know by name (:func:`solver_spec`).
        """
        check_solver(self.name)
        return getattr(import_module(self.module), f"{self.name}_solver")

    @property
    def settings(self) -> type[SolverSettings] | None:
        """Its settings class, None where it takes none (no solver module is imported)."""
        if self.settings_class is None:
            return None
        return getattr(import_module(self.settings_module), self.settings_class)


# The solvers by name; a new solver adds one line here.
SPECS: Mapping[str, SolverSpec] = MappingProxyType(
    {
        s.name: s
        for s in (
            SolverSpec("jm", "hlik.solvers.jm", None, takes_criteria=False, tracks_targets=False),
            SolverSpec("jv", "hlik.solvers.jv", "JVSettings"),
            SolverSpec("qp", "hlik.solvers.qp", "QPSettings"),
            SolverSpec("slsqp", "hlik.solvers.slsqp", "SLSQPSettings"),
            SolverSpec("mink", "hlik.solvers.mink_stack", "MinkSettings"),
        )
    }
)
SOLVER_NAMES = tuple(SPECS)
# a solver's name with this after it: its result optimised over the whole take (hlik.solvers.whole_take)
WHOLE_TAKE = "+whole"


def check_solver(name: str) -> SolverSpec:
    """The spec of solver ``name``.

    Raises:
        UnknownNameError: no solver of that name, with the names there are.
    """
    if name not in SPECS:
        hint = did_you_mean(name, SOLVER_NAMES)
        raise UnknownNameError(f"unknown solver {name!r}{hint}; choose one of: {', '.join(SOLVER_NAMES)}")
    return SPECS[name]


def solver_spec(name: str) -> SolverSpec:
    """The :class:`SolverSpec` of solver ``name``; a solver hlik does not know by name (a user's
    function, a mink stack) is one that tracks the targets and takes no criteria of hlik's. A name
    ending in :data:`WHOLE_TAKE` (a solver's result optimised over the whole take,
    :mod:`hlik.solvers.whole_take`) is its solver's.

    Use it for what a solver can do, not its name."""
    name = name.removesuffix(WHOLE_TAKE)
    return SPECS.get(name) or SolverSpec(name, "", None, takes_criteria=False)


def get_solver(
    name: str,
    settings: object | None = None,
    progress: Callable[[int], None] | None = None,
    limits: Sequence[object] = (),
) -> Solver:
    """The solver called ``name`` with ``settings`` (its settings class; default: the defaults);
    ``progress(k)`` is called after each frame ``k``; ``limits``: a caller's ``mink.Limit``\\ s,
    kept by every optimising solver. The learned pieces of its criteria come with the problem
    (:func:`hlik.problem.build_problem`).

    Raises:
        UnknownNameError: unknown name.
        SettingsError: ``limits`` for a solver that keeps none (JM maps joint angles).
    """
    spec = check_solver(name)
    if limits and not spec.tracks_targets:
        raise SettingsError(f"solver {name} maps joint angles and keeps no limits of a caller's")
    extra = {"limits": tuple(limits)} if limits else {}
    return (
        spec.factory(settings, progress, **extra)
        if settings is not None
        else spec.factory(progress=progress, **extra)
    )
