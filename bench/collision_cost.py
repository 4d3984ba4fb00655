"""What self-collision avoidance costs the QP: time per frame with and without it, same frames.

Each robot retargets the first ``--takes`` KIT takes (``--seconds`` each after the first second,
100 Hz, ``ee_pose`` stack, reach placement) with ``self_collision`` on and off, alternating, in one
process. Prints the median ms per frame of each and their ratio per robot; the issue's target is a
ratio of at most 2. Run by hand: ``python bench/collision_cost.py [--criteria SYN,HJA_r]``.
"""

from __future__ import annotations

import argparse
import os
from dataclasses import replace
from pathlib import Path

import numpy as np

import hlik
from hlik.criteria.learned import learn
from hlik.human.kinematics import forward_kinematics
from hlik.problem.placement import reach_placement
from hlik.solvers import get_solver
from hlik.solvers.stack_file import load_stack

DATA = Path(os.environ.get("HLIK_DATA", Path(__file__).resolve().parents[2] / "shared" / "motion_data"))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", default="armar3,armar6,dual_panda")
    parser.add_argument("--criteria", default="")
    parser.add_argument("--takes", type=int, default=4)
    parser.add_argument("--seconds", type=float, default=3.0)
    args = parser.parse_args()
    takes = sorted((DATA / "kit_bimanual").glob("*.xml"))[: args.takes]
    criteria = [c for c in args.criteria.split(",") if c]
    settings = load_stack("ee_pose").with_criteria(criteria).settings("qp")
    print(f"{len(takes)} takes x {args.seconds:g} s, qp{'+' + '+'.join(criteria) if criteria else ''}")
    print(f"{'robot':11s} {'with ms':>8s} {'without ms':>10s} {'ratio':>6s}")
    for name in args.robots.split(","):
        robot = hlik.load_robot(name)
        learned = learn(robot)
        times: dict[bool, list[np.ndarray]] = {True: [], False: []}
        for take in takes:
            motion = hlik.load_motion(take, rate=100.0)
            motion = motion.crop(1.0, min(1.0 + args.seconds, motion.duration))
            placement = reach_placement(robot, forward_kinematics(motion))
            for on in (True, False):
                solver = get_solver("qp", replace(settings, self_collision=on), learned)
                traj = hlik.retarget(motion, robot, solver, placement)
                times[on].append(traj.diagnostics.solve_time)
        with_ms, without_ms = (1e3 * np.median(np.concatenate(times[on])) for on in (True, False))
        print(f"{name:11s} {with_ms:8.2f} {without_ms:10.2f} {with_ms / without_ms:6.2f}", flush=True)


if __name__ == "__main__":
    main()
