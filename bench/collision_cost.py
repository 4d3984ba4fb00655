"""What self-collision avoidance costs the QP: time per frame with and without it, same frames.

Each robot retargets the first ``--takes`` KIT takes (``--seconds`` each after the first second,
100 Hz, ``ee_pose`` stack, each robot's placement) with ``self_collision`` on and off, alternating, in one
process, ``--repeats`` times. Prints the median CPU ms per frame of each (per take and repeat, the
run's CPU time over its frames) and their ratio per robot; the issue's target is a ratio of at most 2.
Run by hand: ``python bench/collision_cost.py [--criteria SYN,HJA_r]``.
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
from hlik.solvers.qp import solve
from hlik.solvers.stack_file import load_stack

DATA = Path(os.environ.get("HLIK_DATA", Path(__file__).resolve().parents[2] / "shared" / "motion_data"))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", default="armar3,armar6,dual_panda")
    parser.add_argument("--criteria", default="")
    parser.add_argument("--takes", type=int, default=4)
    parser.add_argument("--seconds", type=float, default=3.0)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    takes = sorted((DATA / "kit_bimanual").glob("*.xml"))[: args.takes]
    criteria = [c for c in args.criteria.split(",") if c]
    settings = load_stack("ee_pose").with_criteria(criteria).settings("qp")
    print(f"{len(takes)} takes x {args.seconds:g} s, qp{'+' + '+'.join(criteria) if criteria else ''}")
    print(f"{'robot':11s} {'with ms':>8s} {'without ms':>10s} {'ratio':>6s}")
    for name in args.robots.split(","):
        robot = hlik.load_robot(name)
        learned = learn(robot)
        times: dict[bool, list[float]] = {True: [], False: []}
        for take in takes:
            motion = hlik.load_motion(take, rate=100.0)
            motion = motion.crop(1.0, min(1.0 + args.seconds, motion.duration))
            problem = build_problem(motion, robot, placement_from_spec(robot.placement, robot, motion))
            for r in range(args.repeats):
                for on in (True, False) if r % 2 == 0 else (False, True):
                    start = time.process_time()
                    solve(replace(problem, learned=learned), replace(settings, self_collision=on))
                    times[on].append((time.process_time() - start) / problem.n_frames)
        with_ms, without_ms = (1e3 * np.median(times[on]) for on in (True, False))
        print(f"{name:11s} {with_ms:8.2f} {without_ms:10.2f} {with_ms / without_ms:6.2f}", flush=True)


if __name__ == "__main__":
    main()
