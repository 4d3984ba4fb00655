"""What the look-ahead costs the QP and SLSQP: time per frame with each robot's ``ee_pose`` pull and
with none (``preview_cost = 0``, one pass), on the same frames.

Each robot retargets the first ``--takes`` KIT takes (``--seconds`` each after the first second,
100 Hz, ``ee_pose`` with ``--criteria``, the robot's own stack table and placement) with and without
the look-ahead, alternating, in one process, ``--repeats`` times. Prints per solver and robot the
pull, the median CPU ms per frame of each (per take and repeat: the run's CPU time over its frames,
the path's fit included) and their ratio; two passes make it about 2.
Run by hand: ``python bench/look_ahead.py [--solvers qp,slsqp] [--criteria SYN,HJA_r]``.
"""

from __future__ import annotations

import argparse
import os
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

import hlik
from hlik.criteria.learned import learn
from hlik.problem.placement import placement_from_spec
from hlik.problem.problem import build_problem
from hlik.solvers import qp, slsqp
from hlik.solvers.stack_file import load_stack

DATA = Path(os.environ.get("HLIK_DATA", Path(__file__).resolve().parents[2] / "shared" / "motion_data"))
SOLVE = {"qp": qp.solve, "slsqp": slsqp.solve}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", default="armar3,armar6,dual_panda")
    parser.add_argument("--solvers", default="qp,slsqp")
    parser.add_argument("--criteria", default="SYN,HJA_r")
    parser.add_argument("--takes", type=int, default=2)
    parser.add_argument("--seconds", type=float, default=3.0)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    takes = sorted((DATA / "kit_bimanual").glob("*.xml"))[: args.takes]
    if not takes:
        raise SystemExit(f"{DATA / 'kit_bimanual'}: no takes (set HLIK_DATA)")
    criteria = [c for c in args.criteria.split(",") if c]
    stack = load_stack("ee_pose").with_criteria(criteria)
    print(f"{len(takes)} takes x {args.seconds:g} s, criteria {'+'.join(criteria) or 'none'}")
    print(f"{'solver':7s} {'robot':11s} {'pull':>5s} {'with ms':>8s} {'without ms':>10s} {'ratio':>6s}")
    ratios = []
    for name in args.robots.split(","):
        robot = hlik.load_robot(name)
        learned = learn(robot)
        problems = []
        for take in takes:
            motion = hlik.load_motion(take, rate=100.0)
            motion = motion.crop(1.0, min(1.0 + args.seconds, motion.duration))
            placement = placement_from_spec(robot.placement, robot, motion)
            problems.append(replace(build_problem(motion, robot, placement), learned=learned))
        for solver in args.solvers.split(","):
            settings = stack.settings(solver, name)
            variants = {True: settings, False: replace(settings, preview_cost=0.0)}
            times: dict[bool, list[float]] = {True: [], False: []}
            for problem in problems:
                for r in range(args.repeats):
                    for on in (True, False) if r % 2 == 0 else (False, True):
                        start = time.process_time()
                        SOLVE[solver](problem, variants[on])
                        times[on].append((time.process_time() - start) / problem.n_frames)
            with_ms, without_ms = (1e3 * np.median(times[on]) for on in (True, False))
            ratios.append(with_ms / without_ms)
            print(
                f"{solver:7s} {name:11s} {settings.preview_cost:5g} {with_ms:8.2f} {without_ms:10.2f} "
                f"{with_ms / without_ms:6.2f}",
                flush=True,
            )
    print(f"ratio with/without look-ahead (median): {np.median(ratios):.2f}")


if __name__ == "__main__":
    main()
