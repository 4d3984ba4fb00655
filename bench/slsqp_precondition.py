"""SLSQP per frame, per preconditioner: evaluations and CPU time on the recorded KIT takes.

For each robot, SLSQP (the paper's OPT weights, ``paper_opt``) retargets the same frames (``--seconds``
of ``--takes`` KIT takes after their first second, 100 Hz, each robot's placement) with each
``SLSQPSettings.precondition``: ``none`` (RelaxedIK's raw objective), ``scale`` (divided by its
Gauss-Newton scale) and ``gauss_newton`` (hlik's default: each frame in Gauss-Newton variables),
interleaved over ``--repeats`` so that load on the shared cores hits all alike. Per line: the median
CPU ms per frame, NLopt evaluations per frame, converged and failed frames, m_hl and m_f. The last
line: the CPU speedup of ``gauss_newton`` over ``scale``, the worst over the robots.
Run by hand: ``python bench/slsqp_precondition.py [--robots armar6] [--criteria SYN,HJA_r]``.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

import numpy as np

import hlik
from common import kit_takes
from hlik.criteria.learned import learn
from hlik.metrics import evaluate
from hlik.problem.placement import placement_from_spec
from hlik.solvers import get_solver
from hlik.solvers.slsqp import PRECONDITIONERS
from hlik.solvers.stack_file import load_stack
from hlik.study.dataset import cell_motion


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", default="armar3,armar6,dual_panda")
    parser.add_argument("--criteria", default="", help="comma-separated, e.g. SYN,HJA_r")
    parser.add_argument("--takes", type=int, default=2)
    parser.add_argument("--seconds", type=float, default=1.0)
    parser.add_argument("--repeats", type=int, default=2)
    args = parser.parse_args()
    criteria = tuple(c for c in args.criteria.split(",") if c)
    takes = kit_takes(args.takes)
    speedups = []
    print(
        f"{'robot':<11}{'precondition':<14}{'ms/frame':>9}{'evals':>7}{'conv %':>8}{'failed':>7}"
        f"{'m_hl':>7}{'m_f':>7}"
    )
    for name in args.robots.split(","):
        robot = hlik.load_robot(name)
        learned = learn(robot)
        scenes = []
        for take in takes:
            motion = cell_motion(take, args.seconds, 100.0, robot)  # as a study cell
            scenes.append((motion, placement_from_spec(robot.placement, robot, motion)))
        stats: dict[str, list] = {p: [[], [], [], [], [], []] for p in PRECONDITIONERS}
        for repeat in range(args.repeats):
            order = PRECONDITIONERS if repeat % 2 == 0 else PRECONDITIONERS[::-1]
            for precondition in order:
                settings = load_stack("paper_opt").with_criteria(criteria).settings("slsqp")
                solver = get_solver("slsqp", replace(settings, precondition=precondition))
                cpu, frames, evals, conv, failed, hl, f = 0.0, 0, [], [], 0, [], []
                for motion, placement in scenes:
                    start = time.process_time()
                    traj = hlik.retarget(motion, robot, solver, placement, learned)
                    cpu += time.process_time() - start
                    frames += traj.n_frames
                    d = traj.diagnostics
                    evals.append(d.iterations[1:])
                    conv.append(d.converged[1:])
                    failed += int(d.failed.sum())
                    if repeat == 0:
                        ev = evaluate(traj, robot, learned)
                        hl.append(ev.m_hl)
                        f.append(ev.m_f)
                s = stats[precondition]
                s[0].append(cpu / frames * 1e3)
                if repeat == 0:
                    s[1:] = [
                        np.concatenate(evals).mean(),
                        np.concatenate(conv).mean(),
                        failed,
                        np.mean(hl),
                        np.mean(f),
                    ]
        for precondition in PRECONDITIONERS:
            ms, evals, conv, failed, hl, f = stats[precondition]
            print(
                f"{name:<11}{precondition:<14}{np.median(ms):9.1f}{evals:7.1f}{100 * conv:8.1f}{failed:7d}"
                f"{hl:7.3f}{f:7.3f}"
            )
        speedups.append(np.median(stats["scale"][0]) / np.median(stats["gauss_newton"][0]))
    print(f"speedup gauss_newton over scale (worst robot): {min(speedups):.1f}")


if __name__ == "__main__":
    main()
