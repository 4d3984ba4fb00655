"""What self-collision avoidance costs the QP: time per frame with and without it, same frames.

Each robot retargets the first ``--takes`` KIT takes (``--seconds`` each after the first second,
100 Hz, ``ee_pose`` stack, each robot's placement) with ``self_collision`` on and off, alternating, in one
process, ``--repeats`` times. Prints the median CPU ms per frame of each (per take and repeat, the
run's CPU time over its frames) and their ratio per robot; the issue's target is a ratio of at most 2.
Run by hand: ``python bench/collision_cost.py [--criteria SYN,HJA_r]``.
"""

from __future__ import annotations

import argparse
from dataclasses import replace

import hlik
from common import ab_arguments, ab_cpu_ms, kit_problems, kit_takes
from hlik.solvers.qp import solve
from hlik.solvers.stack_file import load_stack


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ab_arguments(parser, criteria="", takes=4)
    args = parser.parse_args()
    takes = kit_takes(args.takes)
    criteria = [c for c in args.criteria.split(",") if c]
    settings = load_stack("ee_pose").with_criteria(criteria).settings("qp")
    print(f"{len(takes)} takes x {args.seconds:g} s, qp{'+' + '+'.join(criteria) if criteria else ''}")
    print(f"{'robot':11s} {'with ms':>8s} {'without ms':>10s} {'ratio':>6s}")
    for name in args.robots.split(","):
        problems = kit_problems(hlik.load_robot(name), takes, args.seconds)
        variants = {on: replace(settings, self_collision=on) for on in (True, False)}
        with_ms, without_ms = ab_cpu_ms(solve, problems, variants, args.repeats)
        print(f"{name:11s} {with_ms:8.2f} {without_ms:10.2f} {with_ms / without_ms:6.2f}", flush=True)


if __name__ == "__main__":
    main()
