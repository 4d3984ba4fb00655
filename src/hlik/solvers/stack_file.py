"""Task-stack files (``tasks/*.toml``): the targets, the human-likeness criteria and each solver's weights.

A stack file names the scenario (``pose``: both TCPs follow the hands; ``relative``: the relative pose
of the hands), the criteria to add, optionally a ``[gamma]`` table overriding a criterion's Table II
gamma, and one table of settings per solver (``[qp]``, ``[jv]``, ``[slsqp]``, the fields of that
solver's settings class; a ``[qp.gamma]`` table overrides ``[gamma]`` for that solver alone). Each
added criterion weighs ``gamma_i * criterion weight / len(criteria)``, as in the paper. A
``[whole_take]`` table sets the whole-take stage's
(:class:`~hlik.solvers.settings.WholeTakeSettings`; its criteria and gamma are the solver's), and
its ``after`` key the solvers it follows where a run does not say (``--whole-take`` /
``--no-whole-take``), per robot in ``[whole_take.robot.<name>]``.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType

from hlik.criteria import registry
from hlik.robot.files import available_robots
from hlik.solvers.bounds import MAX_WEIGHT
from hlik.solvers.settings import SOLVERS_OWN, WholeTakeSettings
from hlik.util.errors import SettingsError
from hlik.util.paths import tasks_dir
from hlik.util.tomlfile import did_you_mean, read_toml, unknown_key

SCENARIOS = ("pose", "relative")
SOLVER_TABLES = ("qp", "jv", "slsqp", "mink")
STAGE_TABLE = "whole_take"  # the whole-take stage after any of them
TABLES = (*SOLVER_TABLES, STAGE_TABLE)
ROBOT_TABLE = "robot"  # [qp.robot.armar6]: that robot's settings over [qp]'s
AFTER = "after"  # [whole_take] after = ["qp"]: the solvers the stage follows unless a run says


@dataclass(frozen=True)
class Stack:
    """A task stack.

    Attributes:
        name: Stack name (the file stem).
        scenario: ``pose`` or ``relative``.
        criteria: Human-likeness criteria added to the stack (paper names).
        gamma: Criterion name -> scaling weight overriding the criterion's Table II gamma.
        solvers: Solver name -> settings overrides (field name -> value).
        robots: Solver name -> robot name -> that robot's overrides over the solver's
            (``[<solver>.robot.<name>]``).
        path: The file it was read from (None: made in Python); messages name it.
    """

    name: str
    scenario: str = "pose"
    criteria: tuple[str, ...] = ()
    gamma: Mapping[str, float] = field(default_factory=dict)
    solvers: Mapping[str, Mapping[str, object]] = field(default_factory=dict)
    robots: Mapping[str, Mapping[str, Mapping[str, object]]] = field(default_factory=dict)
    path: Path | None = None

    @property
    def where(self) -> str:
        """What messages call the stack: its file, else its name."""
        return str(self.path) if self.path is not None else self.name

    def with_criteria(self, criteria: Sequence[str]) -> Stack:
        """The same stack with other criteria."""
        check_criteria(tuple(criteria), self.name)
        return dataclasses.replace(self, criteria=tuple(criteria))

    def settings(self, solver: str, robot: str | None = None):
        """The settings object of ``solver`` (``qp``, ``jv``, ``slsqp``, ``mink``, or the
        ``whole_take`` stage) for this stack; with ``robot`` (a robot's ``name``), its
        ``[<solver>.robot.<name>]`` table over the solver's."""
        cls = settings_class(solver)
        # [mink] is the QP on mink: it starts from the [qp] table
        layers = ("qp", solver) if solver == "mink" else (solver,)
        table: dict[str, object] = {}
        for s in layers:
            table |= self.solvers.get(s, {})
        for s in layers:  # the robot's own values over every solver table's
            table |= self.robots.get(s, {}).get(robot, {}) if robot is not None else {}
        if solver == STAGE_TABLE:  # its criteria and gamma are the solver's (settings_for)
            table.pop(AFTER, None)  # the stack's choice of runs, not a setting of the stage
            return cls(**table)
        solver_gamma: Mapping[str, float] = table.pop("gamma", {})  # type: ignore[assignment]
        gamma = MappingProxyType({**cls().gamma, **self.gamma, **solver_gamma})  # onto the solver's own
        return cls(criteria=self.criteria, scenario=self.scenario, gamma=gamma, **table)

    def whole_take(self, solver: str, robot: str) -> bool:
        """Whether a run of ``solver`` on ``robot`` (its ``name``) is followed by the whole-take
        stage where it does not say: ``solver`` in ``[whole_take.robot.<robot>]``'s ``after``, else
        in ``[whole_take]``'s (none by default)."""
        after = self.robots.get(STAGE_TABLE, {}).get(robot, {}).get(AFTER)
        if after is None:
            after = self.solvers.get(STAGE_TABLE, {}).get(AFTER, ())
        return solver in after  # type: ignore[operator]

    def near_misses(self, solver: str, robot: str) -> list[str]:
        """Notes on what a run of ``solver`` on ``robot`` leaves unused: ``[<solver>.robot.<name>]``
        and ``[whole_take.robot.<name>]`` tables whose name is close to the robot's (``armar7``
        for ``armar6``: likely a typo; tables for other robots are not refused when the stack is
        read, since a robot's name can be anything), a bundled robot's tables where a user's robot
        is named after it (``dual_panda_raised``: a copy, which they do not tune), and
        ``[mink]``'s own tasks and limits under another solver."""
        layers = (*(("qp", solver) if solver == "mink" else (solver,)), STAGE_TABLE)
        # another bundled robot's table is meant for it (armar6 beside armar3), not a typo
        names = {n for s in layers for n in self.robots.get(s, {})} - {robot, *available_robots()}
        notes = [
            f"{self.where}: [{s}.{ROBOT_TABLE}.{n}] is not used for robot {robot!r}: a typo of {robot!r}?"
            for s in layers
            for n in sorted(self.robots.get(s, {}))
            if n in names and difflib.get_close_matches(n, [robot], n=1, cutoff=0.75)
        ]
        if robot not in available_robots():  # a user's robot named after a bundled one it copies
            notes += [
                f"{self.where}: [{s}.{ROBOT_TABLE}.{n}] tunes the bundled {n}, not robot {robot!r}, which "
                f"gets the stack's defaults (copy the table as [{s}.{ROBOT_TABLE}.{robot}] to use it)"
                for s in layers
                for n in sorted(self.robots.get(s, {}))
                if n in available_robots()
                and (robot.startswith(n) or difflib.get_close_matches(n, [robot], 1, 0.75))
            ]
        own = [k for k in ("tasks", "limits") if self.solvers.get("mink", {}).get(k)]
        if own and solver != "mink":  # mink's own objects are what --solver mink adds to the QP
            unused = " and ".join(own)
            notes.append(f"{self.where}: [mink] {unused} are used by --solver mink only, not {solver}")
        return notes


def settings_class(solver: str) -> type:
    """The frozen settings dataclass of a solver (:class:`~hlik.solvers.settings.SolverSpec`), or
    the whole-take stage's."""
    from hlik.solvers import SPECS

    if solver == STAGE_TABLE:
        return WholeTakeSettings

    spec = SPECS.get(solver)
    if spec is None or spec.settings is None:
        raise SettingsError(f"solver {solver!r} has no settings; choose one of: {', '.join(SOLVER_TABLES)}")
    return spec.settings


def bundled_stacks() -> tuple[str, ...]:
    """Names of the stack files shipped with hlik (``ee_pose``, ``relative_pose``)."""
    return tuple(sorted(p.stem for p in tasks_dir().glob("*.toml")))


def load_stack(path: str | Path) -> Stack:
    """Read a stack file, or a bundled stack by name (``ee_pose``, ``relative_pose``).

    Raises:
        SettingsError: naming the file and the problem (missing, bad TOML, unknown key, bad value).
    """
    path = Path(path)
    if not path.exists() and path.suffix == "" and (tasks_dir() / f"{path}.toml").exists():
        path = tasks_dir() / f"{path}.toml"
    raw = read_toml(path, "stack", bundled_stacks())
    return _parse(raw, path)


def _parse(raw: dict, path: Path) -> Stack:
    allowed = {"name", "scenario", "criteria", "gamma", *TABLES}
    for key in sorted(set(raw) - allowed):  # a solver's setting written above the tables
        owners = [f"[{s}]" for s in TABLES if key in _field_names(s)]
        if owners:
            raise SettingsError(f"{path}: {key} is a solver's setting: put it in {' or '.join(owners)}")
    _check_keys(raw, allowed, path, "the top level")
    scenario = raw.get("scenario", "pose")
    if scenario not in SCENARIOS:
        raise SettingsError(f"{path}: unknown scenario {scenario!r}; choose one of: {', '.join(SCENARIOS)}")
    criteria = raw.get("criteria", [])
    if not isinstance(criteria, list) or not all(isinstance(c, str) for c in criteria):
        raise SettingsError(f'{path}: criteria must be a list of names, e.g. ["SYN", "HJA_r"]')
    check_criteria(tuple(criteria), path)
    gamma = _gamma(raw.get("gamma", {}), path, "gamma")
    solvers, robots = {}, {}
    for solver in (s for s in TABLES if s in raw):
        table = raw[solver]
        if not isinstance(table, dict):
            raise SettingsError(f"{path}: [{solver}] must be a table")
        fields = {f.name: f for f in dataclasses.fields(settings_class(solver))}
        solvers_own = SOLVERS_OWN if solver == STAGE_TABLE else ()
        allowed = _field_names(solver) - {"criteria", "scenario"}
        _check_keys(table, allowed | {ROBOT_TABLE}, path, f"[{solver}]", solvers_own)
        solvers[solver] = MappingProxyType(
            {k: _setting(solver, solver, k, v, fields, path) for k, v in table.items() if k != ROBOT_TABLE}
        )
        own = table.get(ROBOT_TABLE, {})
        if not isinstance(own, dict) or not all(isinstance(t, dict) for t in own.values()):
            raise SettingsError(f"{path}: [{solver}.{ROBOT_TABLE}] must hold one table per robot name")
        for robot, overrides in own.items():
            _check_keys(
                overrides, allowed - {"gamma"}, path, f"[{solver}.{ROBOT_TABLE}.{robot}]", solvers_own
            )
        robots[solver] = MappingProxyType(
            {
                robot: MappingProxyType(
                    {
                        k: _setting(solver, f"{solver}.{ROBOT_TABLE}.{robot}", k, v, fields, path)
                        for k, v in overrides.items()
                    }
                )
                for robot, overrides in own.items()
            }
        )
    name = raw.get("name", path.stem)
    if not isinstance(name, str) or not name.strip():
        raise SettingsError(f"{path}: name must be text, got {name!r}")
    stack = Stack(
        name=name,
        scenario=scenario,
        criteria=tuple(criteria),
        gamma=gamma,
        solvers=MappingProxyType(solvers),
        robots=MappingProxyType(robots),
        path=path,
    )
    stage = [stack.solvers.get(STAGE_TABLE, {}), *stack.robots.get(STAGE_TABLE, {}).values()]
    if scenario != "pose" and any(t.get(AFTER) for t in stage):
        raise SettingsError(
            f"{path}: [{STAGE_TABLE}] {AFTER}: the stage optimises both hands' poses; this stack "
            f"tracks their {scenario} pose, retargeted frame by frame only"
        )
    for solver in TABLES:  # refuse bad values now, naming the file, not when a solver starts
        owner = f"{settings_class(solver).__name__}."
        for robot in (None, *stack.robots.get(solver, {})):
            try:
                stack.settings(solver, robot)
            except SettingsError as e:
                table = solver if robot is None else f"{solver}.{ROBOT_TABLE}.{robot}"
                raise SettingsError(f"{path}: [{table}] {str(e).removeprefix(owner)}") from None
    return stack


def _setting(solver: str, table: str, key: str, value: object, fields: dict, path: Path) -> object:
    """One key of a solver's ``[table]``, checked: ``gamma``, mink's ``tasks``/``limits``, or a value of its
    field's kind."""
    if key == "gamma":
        return _gamma(value, path, f"{table}.gamma")
    if solver == STAGE_TABLE and key == AFTER:
        return _after(value, path, table)
    if solver == "mink" and key in ("tasks", "limits"):
        from hlik.solvers.mink_specs import check_specs

        try:
            return check_specs(value, key)
        except SettingsError as e:
            raise SettingsError(f"{path}: [mink] {e}") from None
    return _value(value, fields[key].default, path, f"[{table}] {key}")


def _after(value: object, path: Path, table: str) -> tuple[str, ...]:
    """``[whole_take]``'s ``after``: the solvers (by table name) the stage follows by default."""
    if not isinstance(value, list) or not all(isinstance(v, str) and v in SOLVER_TABLES for v in value):
        raise SettingsError(
            f"{path}: [{table}] {AFTER} must be a list of solvers among {', '.join(SOLVER_TABLES)}, "
            f'e.g. ["qp", "slsqp"], got {value!r}'
        )
    return tuple(value)


def _gamma(table: object, path: Path, where: str) -> Mapping[str, float]:
    """A ``[gamma]`` table (criterion name -> number), checked."""
    if not isinstance(table, dict):
        raise SettingsError(f"{path}: [{where}] must be a table of criterion = number")
    for name in table:
        check_criteria((name,), f"{path}: [{where}]")
    values = {name: _number(v, path, f"[{where}] {name}") for name, v in table.items()}
    for name, v in values.items():
        if not (math.isfinite(v) and 0 <= v <= MAX_WEIGHT):
            rule = f"a finite number in [0, {MAX_WEIGHT:g}]"
            raise SettingsError(f"{path}: [{where}] {name} must be {rule}, got {v}")
    return MappingProxyType(values)


# weights named as in another solver before every weight was ``<what>_cost`` (mink's name)
RENAMED = {
    **{k: f"{k}_cost" for k in ("position", "orientation", "velocity", "acceleration", "jerk", "trunk")},
    **{k: f"{k}_cost" for k in ("relative_position", "relative_orientation", "criterion")},
    "weight": "criterion_cost",
    "orientation_weight": "orientation_cost",
}


def _field_names(solver: str) -> set[str]:
    """The settings a solver's table takes (the stage's: not what it keeps of its solver, and
    ``after``)."""
    names = {f.name for f in dataclasses.fields(settings_class(solver))}
    return (names - set(SOLVERS_OWN)) | {AFTER} if solver == STAGE_TABLE else names


def _check_keys(table: dict, allowed: set[str], path: Path, where: str, solvers: Sequence[str] = ()) -> None:
    """Refuse an unknown key; ``solvers``: keys the whole-take stage keeps of its solver (here they
    would be overwritten silently), each refused as the solver's."""
    if own := [k for k in solvers if k in table]:
        home = "the top level" if own[0] == "criteria" else "[qp], [jv], [slsqp] or [mink]"
        raise SettingsError(
            f"{path}: {where} {own[0]} is the solver's (the stage keeps it): set it in {home}"
        )
    if problem := unknown_key(table, allowed, where, RENAMED):
        raise SettingsError(f"{path}: {problem}")


def check_criteria(criteria: tuple[str, ...], where: object) -> None:
    """Raises:
    SettingsError: a criterion listed twice, or one that is no human-likeness criterion
        (``where`` begins the message)."""
    twice = sorted({c for c in criteria if criteria.count(c) > 1})
    if twice:
        raise SettingsError(f"{where}: criterion {', '.join(twice)} listed twice")
    known = registry.human_likeness()
    unknown = [c for c in criteria if c not in known]
    if unknown:
        raise SettingsError(
            f"{where}: unknown criteria {', '.join(unknown)}{did_you_mean(unknown[0], known)}; "
            f"choose from: {', '.join(known)}"
        )


def _value(value: object, default: object, path: Path, key: str) -> object:
    """A setting of the default's kind: text, true/false, or a number."""
    if isinstance(default, bool):
        if not isinstance(value, bool):
            raise SettingsError(f"{path}: {key} must be true or false, got {value!r}")
        return value
    if isinstance(default, str):
        if not isinstance(value, str):
            raise SettingsError(f"{path}: {key} must be text, got {value!r}")
        return value
    return _number(value, path, key)


def _number(value: object, path: Path, key: str) -> float | int:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise SettingsError(f"{path}: {key} must be a number, got {value!r}")
    return value
