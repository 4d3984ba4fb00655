"""One QP step on ARMAR-6: hlik's stacked QP against a plain mink.solve_ik, same frames, one process.

hlik: both TCP pose terms, smoothness, two criteria (SYN, HJA_r) and the joint limits.
mink: two FrameTasks, a PostureTask and ConfigurationLimit (daqp for both).
Run by hand: ``python bench/qp_step.py``; the last line is ``ratio hlik/mink: X.XX`` (median time per
step, hlik over mink). The machine has 2 shared cores: read medians and ratios, not absolutes.
"""

from __future__ import annotations

import time

import mink
import mujoco
import numpy as np

import hlik
from hlik.criteria.learned import learn
from hlik.human.kinematics import forward_kinematics
from hlik.paths import demo_motion_path
from hlik.problem.placement import shoulder_placement
from hlik.problem.reference import human_reference
from hlik.problem.targets import hand_targets
from hlik.solvers.frames import sample_at
from hlik.solvers.qp import Assembly, QPSettings, build_terms, step

REPEATS = 5


def main() -> None:
    robot = hlik.load_robot("armar6")
    motion = hlik.load_motion(demo_motion_path(), rate=100.0).crop(2.0, 4.0)
    human = forward_kinematics(motion)
    placement = shoulder_placement(robot, human)
    targets = hand_targets(human, placement)
    settings = QPSettings(criteria=("SYN", "HJA_r"))
    terms = Assembly(build_terms(robot, settings, learn(robot)), robot.dof, settings.damping)
    ref = human_reference(robot, motion, placement)
    q0 = hlik.retarget(motion, robot).q  # JM poses as the configurations stepped from

    data = mujoco.MjData(robot.model)
    config = mink.Configuration(robot.model)
    tcp = [
        mink.FrameTask(f"{s}_tcp", "site", position_cost=10.0, orientation_cost=2.0)
        for s in ("left", "right")
    ]
    posture = mink.PostureTask(robot.model, cost=1e-2)
    posture.set_target(robot.home)
    limits = [mink.ConfigurationLimit(robot.model)]

    def hlik_step(k: int) -> None:
        frame = sample_at(ref, targets, k, np.tile(q0[k], (3, 1)), 0.01)
        step(robot, terms, q0[k], frame, settings, data)

    def mink_step(k: int) -> None:
        config.update(q0[k])
        for i, task in enumerate(tcp):
            rot = mink.SO3.from_matrix(targets.rot[k, i])
            task.set_target(mink.SE3.from_rotation_and_translation(rot, targets.pos[k, i]))
        mink.solve_ik(config, [*tcp, posture], dt=0.01, solver="daqp", limits=limits)

    times = {"hlik": [], "mink": []}
    for _ in range(REPEATS):
        for name, fun in (("mink", mink_step), ("hlik", hlik_step)):
            for k in range(motion.n_frames):
                start = time.perf_counter()
                fun(k)
                times[name].append(time.perf_counter() - start)
    med = {k: float(np.median(v)) for k, v in times.items()}
    for name in ("mink", "hlik"):
        print(
            f"{name}: {1 / med[name]:8.0f} steps/s  (median {1e3 * med[name]:.3f} ms over {len(times[name])})"
        )
    print(f"ratio hlik/mink: {med['hlik'] / med['mink']:.2f}")


if __name__ == "__main__":
    main()
