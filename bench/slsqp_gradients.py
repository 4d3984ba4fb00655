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

import numpy as np

import hlik
from hlik.criteria.learned import learn
from hlik.paths import demo_motion_path
from hlik.problem.problem import build_problem
from hlik.robot.state import robot_state
from hlik.solvers.slsqp import SLSQPSettings, solve

CRITERIA = ("SYN", "HJA_r")


def run(problem, learned, gradients: str) -> tuple[np.ndarray, np.ndarray, object]:
    """Seconds per frame (T - 1,) after the first, fPOS per frame (T,) and the solver's diagnostics."""
    settings = SLSQPSettings(criteria=CRITERIA, gradients=gradients)
    result = solve(problem, settings, learned)
    fpos = np.linalg.norm(robot_state(problem.robot, result.q).tcp - problem.targets.pos, axis=-1).mean(
        axis=-1
    )
    # the first frame runs longer, from the human pose
    return result.diagnostics.solve_time[1:], fpos, result.diagnostics


def main() -> None:
    robot = hlik.load_robot("armar6")
    motion = hlik.load_motion(demo_motion_path(), rate=100.0).crop(2.0, 3.5)
    problem = build_problem(motion, robot)
    learned = learn(robot)

    med = {}
    for gradients in ("analytic", "fd"):
        per_frame, fpos, diagnostics = run(problem, learned, gradients)
        med[gradients] = (float(np.median(per_frame)), float(np.median(fpos)))
        print(
            f"{gradients:>8}: {1e3 * med[gradients][0]:7.2f} ms/frame (median of {len(per_frame)}), "
            f"{np.median(diagnostics.iterations[1:]):.0f} evaluations/frame, "
            f"median fPOS {1e3 * med[gradients][1]:.3f} mm, failed frames {diagnostics.n_failed}"
        )
    print(f"fPOS difference: {1e3 * abs(med['fd'][1] - med['analytic'][1]):.3f} mm")
    print(f"speedup analytic/fd: {med['fd'][0] / med['analytic'][0]:.1f}")


if __name__ == "__main__":
    main()
