"""What the benchmarks share: where the recorded takes are, the KIT takes cut to a span and made
into problems, and an A/B timing that alternates its two variants on the same frames.

Imported by the scripts beside it (``python bench/<name>.py`` puts this folder on ``sys.path``).
"""

from __future__ import annotations

import argparse
import os
import time
from collections.abc import Callable, Mapping
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

DATA = Path(os.environ.get("HLIK_DATA", Path(__file__).resolve().parents[2] / "shared" / "motion_data"))


def ab_arguments(parser: argparse.ArgumentParser, criteria: str, takes: int) -> None:
    """The options of an A/B timing bench: ``--robots``, ``--criteria`` (default ``criteria``),
    ``--takes`` (default ``takes``), ``--seconds`` and ``--repeats``."""
    parser.add_argument("--robots", default="armar3,armar6,dual_panda")
    parser.add_argument("--criteria", default=criteria)
    parser.add_argument("--takes", type=int, default=takes)
    parser.add_argument("--seconds", type=float, default=3.0)
    parser.add_argument("--repeats", type=int, default=3)


def kit_takes(n: int | None = None) -> list[Path]:
    """The first ``n`` (all: None) KIT bimanual takes, sorted by name; exits when there are none."""
    takes = sorted((DATA / "kit_bimanual").glob("*.xml"))[:n]
    if not takes:
        raise SystemExit(f"{DATA / 'kit_bimanual'}: no takes (set HLIK_DATA)")
    return takes


# the columns a floor bench's table starts with: the run's and the floor's fORI median and p95, degrees
FLOOR_HEAD = f"{'robot':10s} {'fORI':>6s} {'fORI95':>7s} {'floor':>6s} {'floor95':>8s}"


def floor_arguments(parser: argparse.ArgumentParser, robots: str) -> None:
    """The options of a floor bench: ``--robots`` (default ``robots``), ``--approach`` (a solver
    and its criteria, ``qp+SYN+HJA_r``), ``--takes`` (8) and ``--seconds`` (5)."""
    parser.add_argument("--robots", default=robots)
    parser.add_argument("--approach", default="qp+SYN+HJA_r")
    parser.add_argument("--takes", type=int, default=8)
    parser.add_argument("--seconds", type=float, default=5.0)


def solved_runs(robot: str, approach: str, takes: list[Path], seconds: float, time_scale: float = 1.0):
    """``(take, hlik.pipeline.RunResult)`` for each take: ``seconds`` after its first second
    retargeted to ``robot`` by ``approach`` (``solver+criterion+...``), as ``hlik run`` does."""
    from hlik.pipeline import RunSpec
    from hlik.pipeline import run as run_pipeline

    solver, *criteria = approach.split("+")
    for take in takes:
        spec = RunSpec(
            motion=take,
            robot=robot,
            solver=solver,
            criteria=tuple(criteria),
            span=(1.0, 1.0 + seconds),
            time_scale=time_scale,
        )
        yield take, run_pipeline(spec)


def kit_problems(robot: Any, takes: list[Path], seconds: float) -> list[Any]:
    """One problem per take: ``seconds`` after its first second at 100 Hz, the robot's placement,
    the criteria learned from the bundled demo (as every bench figure)."""
    import hlik
    from hlik.criteria.learned import learn
    from hlik.problem.placement import placement_from_spec
    from hlik.problem.problem import build_problem

    learned = learn(robot)
    problems = []
    for take in takes:
        motion = hlik.load_motion(take, rate=100.0)
        motion = motion.crop(1.0, min(1.0 + seconds, motion.duration))
        placement = placement_from_spec(robot.placement, robot, motion)
        problems.append(replace(build_problem(motion, robot, placement), learned=learned))
    return problems


def ab_cpu_ms(
    solve: Callable[[Any, Any], object], problems: list[Any], variants: Mapping[bool, Any], repeats: int
) -> tuple[float, float]:
    """Median CPU ms per frame of ``solve(problem, variants[True])`` and of ``variants[False]``
    (per problem and repeat: the solve's CPU time over its frames), the order alternating per
    repeat so that neither gets the warm caches."""
    times: dict[bool, list[float]] = {True: [], False: []}
    for problem in problems:
        for r in range(repeats):
            for on in (True, False) if r % 2 == 0 else (False, True):
                start = time.process_time()
                solve(problem, variants[on])
                times[on].append((time.process_time() - start) / problem.n_frames)
    on_ms, off_ms = (1e3 * float(np.median(times[on])) for on in (True, False))
    return on_ms, off_ms
