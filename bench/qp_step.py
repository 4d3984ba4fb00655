"""Whole QP frames on ARMAR-6: hlik's stacked QP against plain mink.solve_ik, same frames, one process.

Both solve every frame of 2 s of the demo to convergence with the same stopping rule (steps of
at most 20, until no joint moves more than 1e-4 rad), each frame starting from the previous
solution (the first from the clipped mapped human pose). hlik: ``qp.solve`` with both TCP pose
terms, smoothness, SYN and HJA_r and the joint limits, self-collision avoidance off (mink's stack
below has none) and the frame box of ``solvers/limits.py`` off (mink's ConfigurationLimit holds
the position stops only); two more lines show hlik with the frame box, and with it and
self-collision avoidance. mink: two FrameTasks, a PostureTask to the robot's home and
ConfigurationLimit (daqp both). Then the QP (on mink since issue 29) against the QP of a git
revision, ``--against`` (default ``d2f408f``, the last that assembled its own problem for daqp), on
ARMAR-6 over two KIT takes × 2 s (:mod:`mink_qp`, each checkout in a subprocess, alternating). Run
by hand: ``python bench/qp_step.py [--against REV]``; the last lines are ``ratio hlik/mink: X.XX``
(median CPU time per frame, hlik over mink) and ``ratio qp/REV: X.XX``. The machine has 2 shared
cores: read medians and ratios.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import mink
import numpy as np

import hlik
from common import kit_takes
from hlik.criteria.learned import learn
from hlik.problem.problem import build_problem
from hlik.solvers.qp import QPSettings, solve
from hlik.solvers.settings import STOP_MARGIN
from hlik.util.paths import demo_motion_path

REPEATS = 3
MAX_ITER, TOL = 20, 1e-4


def mink_frames(problem) -> tuple[np.ndarray, np.ndarray]:
    """CPU seconds (T,) and steps (T,) per frame of mink.solve_ik iterated to convergence."""
    robot, targets = problem.robot, problem.targets
    config = mink.Configuration(robot.model)
    tcp = [
        mink.FrameTask(f"{s}_tcp", "site", position_cost=10.0, orientation_cost=2.0)
        for s in ("left", "right")
    ]
    posture = mink.PostureTask(robot.model, cost=1e-2)
    posture.set_target(robot.home)
    limits = [mink.ConfigurationLimit(robot.model)]
    # from where hlik's frame loop starts: the clipped mapped human pose (from home, 1 m from the
    # targets, mink's unbounded steps wander off and never settle: 20 steps every frame)
    config.update(np.clip(problem.reference.q_map[0], robot.lower, robot.upper))
    seconds, steps = [], []
    for k in range(problem.n_frames):
        start = time.process_time()
        for i, task in enumerate(tcp):
            rot = mink.SO3.from_matrix(targets.rot[k, i])
            task.set_target(mink.SE3.from_rotation_and_translation(rot, targets.pos[k, i]))
        n = 0
        while n < MAX_ITER:
            dq = mink.solve_ik(config, [*tcp, posture], dt=1.0, solver="daqp", limits=limits)
            config.integrate_inplace(dq, 1.0)
            n += 1
            if np.max(np.abs(dq)) < TOL:
                break
        seconds.append(time.process_time() - start)
        steps.append(n)
    return np.array(seconds), np.array(steps)


def hlik_frames(problem, settings, learned) -> tuple[float, np.ndarray]:
    """CPU seconds per frame (mean over the run) and steps per frame of hlik's QP."""
    start = time.process_time()
    result = solve(replace(problem, learned=learned), settings)
    return (time.process_time() - start) / problem.n_frames, result.diagnostics.iterations


def against(revision: str) -> float:
    """This checkout's QP over the QP of ``revision``: median CPU time per frame, ARMAR-6, two KIT
    takes x 2 s, SYN + HJA_r (:mod:`mink_qp`)."""
    import mink_qp  # beside this file

    takes = kit_takes(2)
    ms: dict[str, list[float]] = {"qp": [], revision: []}
    with tempfile.TemporaryDirectory() as tmp:
        sources = {"qp": mink_qp.ROOT / "src", revision: mink_qp.checkout(revision, Path(tmp))}
        for _ in range(REPEATS):
            for label, src in sources.items():
                ms[label].append(mink_qp.run(src, "armar6", "SYN,HJA_r", 2.0, takes)["ms"])
    for label, values in ms.items():
        name = "qp" if label == "qp" else f"qp at {label}"
        print(f"{name:26s} {np.median(values):7.2f} ms/frame (CPU, KIT takes)")
    return float(np.median(ms["qp"]) / np.median(ms[revision]))


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--against", default="d2f408f", help="git revision of the QP to compare with")
    args = parser.parse_args()
    robot = hlik.load_robot("armar6")
    motion = hlik.load_motion(demo_motion_path(), rate=100.0).crop(2.0, 4.0)
    problem = build_problem(motion, robot)
    learned = learn(robot)
    # mink's stack has the position stops only: hlik's without the frame box's speed, acceleration,
    # torque rows and stop margin for the ratio, with them (and with collisions) for their cost
    plain = QPSettings(
        preview_cost=0.0,  # frame by frame, as mink: the look-ahead's two passes are not a step's cost
        criteria=("SYN", "HJA_r"),
        self_collision=False,
        max_iter=MAX_ITER,
        tol=TOL,
        acceleration_limits=False,
        torque_limits=False,
        stop_margin=0.0,
    )
    limited = replace(plain, acceleration_limits=True, torque_limits=True, stop_margin=STOP_MARGIN)
    names = ("mink", "hlik", "hlik + limits", "hlik + limits + collisions")
    runs: dict[str, list[float]] = {name: [] for name in names}
    steps: dict[str, float] = {}
    for _ in range(REPEATS):
        seconds, n = mink_frames(problem)
        runs["mink"].append(float(np.mean(seconds[1:])))
        steps["mink"] = float(np.mean(n[1:]))
        for name, settings in (
            ("hlik", plain),
            ("hlik + limits", limited),
            ("hlik + limits + collisions", replace(limited, self_collision=True)),
        ):
            per_frame, n = hlik_frames(problem, settings, learned)
            runs[name].append(per_frame)
            steps[name] = float(np.mean(n[1:]))
    med = {k: float(np.median(v)) for k, v in runs.items()}
    for name, value in med.items():
        print(f"{name:26s} {1e3 * value:7.2f} ms/frame (CPU, median of {REPEATS}), {steps[name]:.1f} steps")
    revision = against(args.against)
    print(f"ratio hlik/mink: {med['hlik'] / med['mink']:.2f}")
    print(f"ratio qp/{args.against}: {revision:.2f}")


if __name__ == "__main__":
    main()
