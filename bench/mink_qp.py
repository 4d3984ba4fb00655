"""hlik's stacked QP against the same stack solved by mink (issue 29: one QP, on mink).

The mink run is :meth:`MinkSolver.from_settings <hlik.solvers.mink_ik.MinkSolver.from_settings>`:
every term of the QP's stack (``qp.build_terms``: both TCP pose terms, smoothness, the criteria,
with the QP's weights; the first frame's stack for the first frame) as a
:class:`~hlik.solvers.mink_tasks.CriterionTask` sharing one kinematics pass, the same frame box,
self-collision rows, step bound, damping and stopping rule. What the QP has that it lacks: soft
torque and collision rows where no step meets them all (mink's limits are hard: it drops the
collision rows, then the torque rows, whole), the hands' band. Same takes, one process, the two
alternating; CPU time per frame (median of the repeats) and the scores of each. Run by hand:
``python bench/mink_qp.py [--robots armar6] [--takes 2] [--seconds 2]``; the last line is
``ratio mink/qp: X.XX`` (median CPU per frame).
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np

import hlik
from hlik.criteria.functional import position_error, rotation_angle
from hlik.criteria.learned import learn
from hlik.metrics import evaluate
from hlik.problem.placement import placement_from_spec
from hlik.problem.scale import scale_subject
from hlik.solvers import get_solver
from hlik.solvers.mink_ik import MinkSolver
from hlik.solvers.stack_file import load_stack

REPEATS = 3  # qp and mink alternate: the machine's load moves both alike
DATA = Path(os.environ.get("HLIK_DATA", Path(__file__).resolve().parents[2] / "shared" / "motion_data"))


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--robots", default="armar3,armar6,dual_panda")
    parser.add_argument("--criteria", default="SYN,HJA_r")
    parser.add_argument("--takes", type=int, default=2)
    parser.add_argument("--seconds", type=float, default=2.0)
    args = parser.parse_args()
    takes = sorted((DATA / "kit_bimanual").glob("*.xml"))[: args.takes]
    criteria = [c for c in args.criteria.split(",") if c]
    print(
        f"{'robot':11s} {'solver':6s} {'ms/frame':>8s} {'steps':>6s} {'m_hl':>6s} {'m_f':>6s} "
        f"{'fPOS cm':>7s} {'fORI':>5s} {'failed':>6s}"
    )
    ratios = []
    for name in args.robots.split(","):
        robot, rows = hlik.load_robot(name), {}
        learned = learn(robot)
        settings = load_stack("ee_pose").with_criteria(criteria).settings("qp")
        mink_solver = MinkSolver.from_settings(robot, settings, learned)
        for label, solver in (("qp", get_solver("qp", settings)), ("mink", mink_solver)) * REPEATS:
            cpu, frames, steps, hl, f, fpos, fori, failed = 0.0, 0, [], [], [], [], [], 0
            for take in takes:
                motion = hlik.load_motion(take, rate=100.0)
                motion = scale_subject(motion.crop(1.0, min(1.0 + args.seconds, motion.duration)), robot)
                where = placement_from_spec(robot.placement, robot, motion)
                start = time.process_time()
                traj = hlik.retarget(motion, robot, solver, where, learned)
                cpu += time.process_time() - start
                frames += traj.n_frames
                ev = evaluate(traj, robot, learned)
                steps.append(traj.diagnostics.iterations[1:])
                hl.append(ev.m_hl)
                f.append(ev.m_f)
                fpos.append(position_error(traj.tcp_pos, traj.targets.pos).ravel())
                fori.append(rotation_angle(traj.tcp_rot, traj.targets.rot).ravel())
                failed += traj.diagnostics.n_failed
            rows.setdefault(label, []).append(1e3 * cpu / frames)
            print(
                f"{name:11s} {label:6s} {rows[label][-1]:8.2f} {np.mean(np.concatenate(steps)):6.1f} "
                f"{np.mean(hl):6.3f} {np.mean(f):6.3f} {100 * np.median(np.concatenate(fpos)):7.2f} "
                f"{np.degrees(np.median(np.concatenate(fori))):5.1f} {failed:6d}",
                flush=True,
            )
        ratios.append(float(np.median(rows["mink"]) / np.median(rows["qp"])))
    print(f"ratio mink/qp: {np.median(ratios):.2f} (per robot: {', '.join(f'{r:.2f}' for r in ratios)})")


if __name__ == "__main__":
    main()
