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
from dataclasses import replace

import numpy as np

import hlik
from common import ab_arguments, ab_cpu_ms, kit_problems, kit_takes
from hlik.solvers import qp, slsqp
from hlik.solvers.stack_file import load_stack

SOLVE = {"qp": qp.solve, "slsqp": slsqp.solve}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ab_arguments(parser, criteria="SYN,HJA_r", takes=2)
    parser.add_argument("--solvers", default="qp,slsqp")
    args = parser.parse_args()
    takes = kit_takes(args.takes)
    criteria = [c for c in args.criteria.split(",") if c]
    stack = load_stack("ee_pose").with_criteria(criteria)
    print(f"{len(takes)} takes x {args.seconds:g} s, criteria {'+'.join(criteria) or 'none'}")
    print(f"{'solver':7s} {'robot':11s} {'pull':>5s} {'with ms':>8s} {'without ms':>10s} {'ratio':>6s}")
    ratios = []
    for name in args.robots.split(","):
        problems = kit_problems(hlik.load_robot(name), takes, args.seconds)
        for solver in args.solvers.split(","):
            settings = stack.settings(solver, name)
            variants = {True: settings, False: replace(settings, preview_cost=0.0)}
            with_ms, without_ms = ab_cpu_ms(SOLVE[solver], problems, variants, args.repeats)
            ratios.append(with_ms / without_ms)
            print(
                f"{solver:7s} {name:11s} {settings.preview_cost:5g} {with_ms:8.2f} {without_ms:10.2f} "
                f"{with_ms / without_ms:6.2f}",
                flush=True,
            )
    print(f"ratio with/without look-ahead (median): {np.median(ratios):.2f}")


if __name__ == "__main__":
    main()
