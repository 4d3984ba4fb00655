"""SLSQP per frame on ARMAR-6: analytic gradients against the paper's forward differences, one process.

Both solve the same frames (1.5 s of the demo motion at 100 Hz, end-effector pose scenario, SYN and
HJA_r, the paper's weights) with NLopt's SLSQP; only ``SLSQPSettings.gradients`` differs. ``fd``
costs n + 1 forward-kinematics passes and term evaluations per gradient, ``analytic`` one.
Run by hand: ``python bench/slsqp_gradients.py``; it prints the median time per frame and the
median fPOS of both, and last ``speedup analytic/fd: X.X`` (median fd time per frame over median
analytic time; target >= 5 with median fPOS within 1 mm). The machine has 2 shared cores: read
medians and ratios, not absolutes.
"""

from __future__ import annotations

import time

import numpy as np

import hlik
from hlik.criteria.learned import learn
from hlik.human.kinematics import forward_kinematics
from hlik.paths import demo_motion_path
from hlik.problem.placement import shoulder_placement
from hlik.problem.targets import hand_targets
from hlik.robot.state import robot_state
from hlik.solvers.slsqp import SLSQPSettings, solve

CRITERIA = ("SYN", "HJA_r")


def run(robot, motion, placement, targets, learned, gradients: str) -> tuple[np.ndarray, np.ndarray, object]:
    """Seconds per frame (T - 1,) after the first, fPOS per frame (T,) and the solver's info."""
    stamps = [time.perf_counter()]
    settings = SLSQPSettings(criteria=CRITERIA, gradients=gradients)
    progress = lambda k: stamps.append(time.perf_counter())  # noqa: E731
    q, info = solve(robot, motion, targets, placement, settings, learned, progress)
    fpos = np.linalg.norm(robot_state(robot, q).tcp - targets.pos, axis=-1).mean(axis=-1)
    return np.diff(stamps)[1:], fpos, info  # the first frame runs longer, from the human pose


def main() -> None:
    robot = hlik.load_robot("armar6")
    motion = hlik.load_motion(demo_motion_path(), rate=100.0).crop(2.0, 3.5)
    placement = shoulder_placement(robot, forward_kinematics(motion))
    targets = hand_targets(forward_kinematics(motion), placement)
    learned = learn(robot)

    med = {}
    for gradients in ("analytic", "fd"):
        per_frame, fpos, info = run(robot, motion, placement, targets, learned, gradients)
        med[gradients] = (float(np.median(per_frame)), float(np.median(fpos)))
        print(
            f"{gradients:>8}: {1e3 * med[gradients][0]:7.2f} ms/frame (median of {len(per_frame)}), "
            f"{np.median(info.evaluations[1:]):.0f} evaluations/frame, "
            f"median fPOS {1e3 * med[gradients][1]:.3f} mm, failed frames {len(info.failed)}"
        )
    print(f"fPOS difference: {1e3 * abs(med['fd'][1] - med['analytic'][1]):.3f} mm")
    print(f"speedup analytic/fd: {med['fd'][0] / med['analytic'][0]:.1f}")


if __name__ == "__main__":
    main()
