"""What one retargeting run is (:class:`RunSpec`), checked whole before anything is read.

This module imports nothing heavy: :meth:`RunSpec.check` answers a typo (an unknown solver, robot,
criterion or format, a rate out of range, a missing file) before NumPy, MuJoCo or SciPy load, so
the CLI's usage errors take a fraction of a second. :func:`hlik.pipeline.run` runs a spec.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType

from hlik.human.formats import motion_format
from hlik.human.limits import RATE_RANGE, scale_factor
from hlik.robot.files import robot_defaults, robot_toml
from hlik.solvers.catalog import SPECS, check_solver, solver_spec
from hlik.solvers.stack_file import SCENARIOS, Stack, check_criteria, load_stack
from hlik.util.errors import HlikError, SettingsError
from hlik.util.paths import demo_motion_path

# the placement rules by name: hlik.problem.placement.PLACEMENTS and hlik run's own ``optimize``
# (the same, tested), named here so that a misspelt rule is answered before NumPy loads
PLACEMENT_RULES = ("reach", "mapped", "working", "shoulders", "optimize")

GRADIENTS = ("analytic", "fd")
# how much slower (or faster) a run may play a motion than recorded
TIME_SCALE_RANGE = (0.1, 10.0)
# the export formats (hlik.export.WRITERS, tested equal), named here for the same reason
EXPORT_FORMATS = ("csv", "mcap", "lerobot")


@dataclass(frozen=True)
class RunSpec:
    """What to retarget, to which robot, how.

    Attributes:
        motion: Motion file (any format :func:`hlik.human.load.load_motion` reads); None: the
            bundled demo.
        robot: Robot name (``hlik robots``) or path of a robot ``.toml``.
        solver: ``jm``, ``jv``, ``qp``, ``slsqp`` or ``mink``. Default ``qp``: on every bundled
            robot the only one whose motion keeps the hands on target, every limit and
            the human likeness at once in milliseconds a frame (README "How they compare").
        stack: Task-stack ``.toml`` or a bundled stack's name; its weights and criteria (the
            criteria only for a solver that adds them: ``jm`` maps the joints).
        criteria: Criteria replacing the stack's (None: the stack's; ``()``: none).
        scenario: ``pose`` or ``relative`` (None: the stack's).
        placement: Placement rule or ``X,Y,YAW[,Z]`` (None: the robot's), ``optimize`` included.
        scale: Subject scale, a factor or ``auto`` (None: the robot's ``subject_scale``).
        rate: Resample the motion to this rate, Hz; 0 keeps the recorded rate.
        span: ``(start, stop)`` s after the first frame to keep (a start at or after the take's
            end is refused, a stop after it is cut there); None: all of it.
        time_scale: Play the (cropped) motion this many times as long, 2: at half its speed
            (:data:`TIME_SCALE_RANGE`); 1: as recorded.
        corpus: Corpus folder the criteria are learned from (None: ``learn``'s default).
        metric: Metric file with the unified metric's weights and x0 (None: Table III).
        gradients: SLSQP's gradients, ``analytic`` or ``fd`` (finite differences, as the paper).
        settings: Solver settings fields to override, name -> value (``bench --set``).
        whole_take: Optimise the solver's result over the whole take at once
            (:mod:`hlik.solvers.whole_take`, keeping the solver's limits; a stack tracking both
            hands' poses, a solver other than ``jm``); None: as the stack chooses for the solver
            and robot (its ``[whole_take]`` ``after``, :meth:`follows_whole_take`).
    """

    motion: Path | None = None
    robot: str | Path = "armar6"
    solver: str = "qp"
    stack: str | Path = "ee_pose"
    criteria: tuple[str, ...] | None = None
    scenario: str | None = None
    placement: str | None = None
    scale: float | str | None = None
    rate: float = 100.0
    span: tuple[float, float] | None = None
    time_scale: float = 1.0
    corpus: Path | None = None
    metric: Path | None = None
    gradients: str = "analytic"
    settings: Mapping[str, object] = field(default_factory=lambda: MappingProxyType({}))
    whole_take: bool | None = None

    @property
    def motion_path(self) -> Path:
        return Path(self.motion) if self.motion is not None else demo_motion_path()

    def task_stack(self) -> Stack:
        """The stack with this spec's criteria (none for a solver that adds none).

        Raises:
            HlikError: the stack file is missing or malformed, or names an unknown criterion.
        """
        stack = load_stack(self.stack)
        if not solver_spec(self.solver).takes_criteria:
            return stack.with_criteria([])  # jm maps the joints: the stack's criteria are the others'
        return stack.with_criteria(list(self.criteria)) if self.criteria is not None else stack

    def follows_whole_take(self, robot: str | None = None, stack: Stack | None = None) -> bool:
        """Whether the whole-take stage follows the solver: :attr:`whole_take` where given, else
        the stack's choice (:meth:`Stack.whole_take`) for the robot named ``robot`` (None: this
        spec's, its description's ``name``); ``stack``: :meth:`task_stack` already read."""
        if self.whole_take is not None:
            return self.whole_take
        name = robot if robot is not None else robot_defaults(str(self.robot)).name
        return (stack or self.task_stack()).whole_take(self.solver, name)

    def check(self) -> Stack:
        """Every setting that can be checked without reading the motion; returns the task stack.

        Names, numbers and files first, with nothing heavy imported (a typo is answered in a
        fraction of a second, ``bench/cli_errors.py``); then the stack file's contents and the
        metric file, which load the solvers' settings classes.

        Raises:
            HlikError: one line naming the setting (or file) and what it accepts.
        """
        for name in ("robot", "stack", "motion", "corpus", "metric"):
            value = getattr(self, name)
            optional = value is None and name not in ("robot", "stack")
            if not (optional or isinstance(value, str | os.PathLike)):
                raise SettingsError(f"RunSpec.{name} must be a name or a path, got {value!r}")
        if isinstance(self.criteria, str):  # ("SYN") for ("SYN",) read as S, Y, N
            raise SettingsError(f"RunSpec.criteria must be a sequence of names, got {self.criteria!r}")
        solver = check_solver(self.solver)
        if self.gradients not in GRADIENTS:
            raise SettingsError(f"unknown gradients {self.gradients!r}; choose analytic or fd")
        if self.gradients == "fd" and self.solver != "slsqp":
            raise SettingsError("--gradients fd is for --solver slsqp")
        low, high = RATE_RANGE
        if not (self.rate == 0 or low <= self.rate <= high):  # NaN fails both
            raise SettingsError(
                f"--rate must be positive, {low:g} to {high:g} Hz (or 0 to keep the motion's rate), "
                f"got {self.rate:g}"
            )
        low, high = TIME_SCALE_RANGE
        if not (low <= self.time_scale <= high):  # NaN fails both
            raise SettingsError(
                f"--time-scale must be {low:g} to {high:g} (2: the motion played at half its speed), "
                f"got {self.time_scale:g}"
            )
        if self.scale is not None:
            scale_factor(self.scale)
        if self.scenario is not None and self.scenario not in SCENARIOS:
            raise SettingsError(f"unknown scenario {self.scenario!r}; choose one of: {', '.join(SCENARIOS)}")
        if self.criteria is not None:
            check_criteria(self.criteria, "--criteria")
        _check_base_pose(self.placement)
        robot_toml(str(self.robot))
        if self.motion is not None:
            motion_format(self.motion)
        if self.corpus is not None and str(self.corpus) == "demo" and not Path(self.corpus).exists():
            raise SettingsError("RunSpec.corpus 'demo': in Python the bundled demo is corpus=None")
        for what, path in (("--metric", self.metric), ("--corpus", self.corpus)):
            if path is not None and not Path(path).exists():
                raise SettingsError(f"{path} ({what}): no such file or folder")
        stack = self.task_stack()
        if self.criteria and not solver.takes_criteria:
            takers = ", ".join(n for n, s in SPECS.items() if s.takes_criteria)
            raise SettingsError(
                f"{self.solver} maps joints and cannot add criteria; choose --solver {takers}"
            )
        if self.whole_take and stack.scenario != "pose":  # what the solver tracks: the stack's
            raise SettingsError(
                f"--whole-take optimises both hands' poses; the stack {stack.name} tracks their "
                f"{stack.scenario} pose, retargeted frame by frame only"
            )
        if self.whole_take and not solver.tracks_targets:
            trackers = ", ".join(n for n, s in SPECS.items() if s.tracks_targets)
            raise SettingsError(
                f"--whole-take starts from a motion within the limits; {self.solver} maps the joints "
                f"and keeps none: choose --solver {trackers}"
            )
        if self.metric is not None:
            from hlik.criteria.unified import load_metric  # NumPy: after the quick checks

            load_metric(self.metric)  # read again by run(): a bad file fails before the solve
        return stack


def _check_base_pose(spec: str | None) -> None:
    """A placement rule by name, or ``X,Y,YAW[,Z]`` of finite numbers (a NaN base pose scores NaN
    without a word), checked before the placement module (NumPy, SciPy) loads."""
    if spec is None or spec in PLACEMENT_RULES:
        return
    try:
        values = [float(v) for v in spec.split(",")]
    except ValueError:
        values = []
    if len(values) not in (3, 4):
        raise HlikError(
            f"placement {spec!r}: expected one of {', '.join(PLACEMENT_RULES[:-1])}, X,Y,YAW (m, m, deg), "
            "X,Y,YAW,Z (and the base height, m) or, in hlik run, optimize (hlik.placement_search in Python)"
        )
    if not all(math.isfinite(v) for v in values):
        raise HlikError(f"--placement {spec}: X, Y, YAW (and Z) must be finite numbers (m, m, deg, m)")
