"""What a study runs: approaches (a solver, the criteria it adds, a scenario, a task stack) read
from an approach file (``study/paper.toml`` is the paper's)."""

from __future__ import annotations

import fnmatch
from dataclasses import dataclass
from pathlib import Path

from hlik.criteria import registry
from hlik.solvers import SOLVER_NAMES, SPECS
from hlik.util.errors import HlikError
from hlik.util.tomlfile import read_toml, unknown_key

PAPER = Path(__file__).with_name("paper.toml")
BUNDLED = ("paper", "quick")  # approach files shipped beside this module, usable by name


@dataclass(frozen=True)
class Approach:
    """One retargeting approach of a study.

    Attributes:
        solver: ``jm``, ``jv``, ``qp`` or ``slsqp``.
        criteria: Human-likeness criteria it adds (paper names).
        scenario: ``pose`` or ``relative``.
        stack: Task stack (bundled name or file) giving the solver's weights.
        correlation: Part of the dataset the metric is derived from (at most one criterion).
    """

    solver: str
    criteria: tuple[str, ...] = ()
    scenario: str = "pose"
    stack: str = "paper_opt"
    correlation: bool = False

    @property
    def name(self) -> str:
        """``qp+SYN+HJA_r``, with `` (relative)`` for the relative-pose scenario."""
        name = "+".join((self.solver, *self.criteria))
        return name if self.scenario == "pose" else f"{name} (relative)"

    @property
    def key(self) -> str:
        """The name as a file-name part: ``qp-SYN-HJA_r`` or ``qp-SYN-relative``."""
        return "-".join((self.solver, *self.criteria, *(() if self.scenario == "pose" else ("relative",))))


def load_approaches(path: str | Path = PAPER) -> tuple[Approach, ...]:
    """The approaches of an approach file (or a bundled one by name: ``paper``, ``quick``), each
    once, correlation ones first.

    Raises:
        HlikError: one line naming the file and what is wrong in it.
    """
    path = Path(__file__).with_name(f"{path}.toml") if str(path) in BUNDLED else Path(path)
    raw = read_toml(path, "approach", BUNDLED)
    if problem := unknown_key(raw, {"stacks", "correlation", "evaluation", "exclude"}, "the top level"):
        raise HlikError(f"{path}: {problem}")
    exclude = raw.get("exclude", [])
    if not isinstance(exclude, list) or not all(isinstance(e, str) for e in exclude):
        raise HlikError(f'{path}: exclude must be a list of approach names or patterns, e.g. ["jv+MJE"]')
    stacks = {"pose": "paper_opt", "relative": "relative_pose"} | dict(raw.get("stacks", {}))
    corr, ev = raw.get("correlation", {}), raw.get("evaluation", {})
    _check_tables(path, corr, ev, raw.get("stacks", {}))
    single = corr.get("single_criteria", False)
    if not isinstance(single, bool):
        raise HlikError(f"{path}: correlation.single_criteria must be true or false")
    out: list[Approach] = []
    for solver in _solvers(corr, path, "correlation"):
        out.append(Approach(solver, stack=stacks["pose"], correlation=True))
        if single and SPECS[solver].takes_criteria:
            for c in registry.human_likeness():
                out.append(Approach(solver, (c,), stack=stacks["pose"], correlation=True))
    pairs = ev.get("pairs", [])
    if not isinstance(pairs, list) or not all(isinstance(p, list) and 1 <= len(p) <= 2 for p in pairs):
        raise HlikError(
            f'{path}: evaluation.pairs must be a list of one or two names, e.g. [["SYN", "HJA_r"]]'
        )
    for scenario in ev.get("scenarios", ["pose"]):
        if scenario not in stacks:
            raise HlikError(f"{path}: unknown scenario {scenario!r} in evaluation.scenarios (pose, relative)")
        for solver in _solvers(ev, path, "evaluation"):
            takes = SPECS[solver].takes_criteria
            groups = [()] if scenario != "pose" or not takes else []
            # [a, b] and [b, a] are one approach: the criteria's order changes nothing
            unique: dict[tuple, tuple] = {}
            for p in pairs:
                unique.setdefault(tuple(sorted(p)), tuple(p))
            groups += list(unique.values()) if takes else []
            for criteria in groups:
                _check_criteria(criteria, path)
                out.append(Approach(solver, criteria, scenario, stacks[scenario]))
    seen: dict[str, Approach] = {}
    for a in out:
        if not any(fnmatch.fnmatchcase(a.name, pattern) for pattern in exclude):
            seen.setdefault(a.name, a)
    unused = [e for e in exclude if not any(fnmatch.fnmatchcase(a.name, e) for a in out)]
    if unused:
        raise HlikError(
            f"{path}: exclude: {unused[0]!r} matches no approach (names as in 'jv+MJE (relative)')"
        )
    if not any(a.correlation for a in seen.values()):
        raise HlikError(f"{path}: no approach for the correlation (a [correlation] table with solvers)")
    return tuple(seen.values())


def _check_tables(path: Path, corr: object, ev: object, stacks: object) -> None:
    """Each of the file's tables a table, with none but its own keys."""
    for where, table, allowed in (
        ("[correlation]", corr, ("solvers", "single_criteria")),
        ("[evaluation]", ev, ("solvers", "pairs", "scenarios")),
        ("[stacks]", stacks, ("pose", "relative")),
    ):
        if not isinstance(table, dict):
            raise HlikError(f"{path}: {where} must be a table")
        if problem := unknown_key(table, allowed, where):
            raise HlikError(f"{path}: {problem}")


def _solvers(table: dict, path: Path, where: str) -> list[str]:
    solvers = table.get("solvers", [])
    if not isinstance(solvers, list):
        raise HlikError(f'{path}: {where}.solvers must be a list, e.g. ["jm", "qp"]')
    bad = [s for s in solvers if s not in SOLVER_NAMES]
    if bad:
        raise HlikError(f"{path}: {where}.solvers: unknown solver {bad[0]!r}")
    return solvers


def _check_criteria(criteria: tuple[str, ...], path: Path) -> None:
    bad = [c for c in criteria if c not in registry.human_likeness()]
    if bad:
        raise HlikError(f"{path}: unknown criterion {bad[0]!r} in evaluation.pairs")
