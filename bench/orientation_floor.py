"""How far the robot's joint ranges, not the solver, keep the hands off their target orientation.

For every ``--every``-th frame of a solved run, a static IK (SciPy's SLSQP, all joints, no speed or
acceleration limit) looks for the configuration inside the joint ranges (less the solvers' stop
margin) that turns both TCPs closest to their target orientations while each TCP stays within
``--tol`` of its target position, seeded from the solved frame. Its orientation errors are the
*floor* near that configuration: what no weight or criterion could remove without leaving the
joint ranges (a local floor: another branch of the arm could do better; ``--seeds N`` adds N starts
drawn uniformly inside the ranges and keeps the best, the floor over the branches they find). The
table compares the
solver's median (p95) hand orientation error with the floor's, and names the joints the floor
leaves at a stop. ``--widen J1,J2`` widens those joints' ranges by 90 deg each way in the floor's IK
(not in the solve), to show which range binds.

Run by hand: ``python bench/orientation_floor.py [--robots armar3,dual_panda] [--approach
qp+SYN+HJA_r] [--takes 8] [--seconds 5] [--every 10] [--seeds 0]``.
"""

from __future__ import annotations

import argparse
from collections import Counter

import mujoco
import numpy as np
from scipy.optimize import minimize

import hlik
from common import FLOOR_HEAD, floor_arguments, kit_takes, solved_runs
from hlik.criteria.functional import rotation_angle
from hlik.robot.model import SIDES

STOP_MARGIN = np.radians(3.0)  # the solvers' default stop margin (QPSettings.stop_margin)


def floor_pose(
    robot: hlik.Robot,
    q0: np.ndarray,
    pos: np.ndarray,
    rot: np.ndarray,
    tol: float,
    widen: np.ndarray,
    seeds: int = 0,
    rng: np.random.Generator | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """(n,) the configuration near ``q0`` (or near one of ``seeds`` random starts inside the
    ranges, whichever is better) turning both TCPs closest to ``rot`` (2, 3, 3) with each within
    ``tol`` m of ``pos`` (2, 3), base frame; and (2,) its orientation errors, rad (``q0``, clipped,
    where no start meets the position bound)."""
    rng = rng or np.random.default_rng(0)
    model, data = robot.model, mujoco.MjData(robot.model)
    sites = [robot.site_id(s, "tcp") for s in SIDES]
    lo = np.where(np.isinf(robot.lower), -np.inf, robot.lower + STOP_MARGIN - widen)
    hi = np.where(np.isinf(robot.upper), np.inf, robot.upper - STOP_MARGIN + widen)
    jp, jr = np.zeros((3, model.nv)), np.zeros((3, model.nv))

    def state(q: np.ndarray) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
        data.qpos[:] = q  # the models' qpos are the joints, in order (robots/README.md)
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        out = []
        for s in sites:
            mujoco.mj_jacSite(model, data, jp, jr, s)
            out.append(
                (data.site_xpos[s].copy(), data.site_xmat[s].reshape(3, 3).copy(), jp.copy(), jr.copy())
            )
        return out

    def objective(q: np.ndarray) -> tuple[float, np.ndarray]:
        f, g = 0.0, np.zeros_like(q)
        for a, (_, r, _, wr) in enumerate(state(q)):
            f += 2.0 * (3.0 - np.trace(rot[a].T @ r))  # ||R - R*||_F^2, monotonic in the angle
            m = r @ rot[a].T
            g += 2.0 * np.array([m[2, 1] - m[1, 2], m[0, 2] - m[2, 0], m[1, 0] - m[0, 1]]) @ wr
        return f, g

    def within(q: np.ndarray) -> np.ndarray:
        return np.array([tol**2 - np.sum((p - pos[a]) ** 2) for a, (p, _, _, _) in enumerate(state(q))])

    def within_jac(q: np.ndarray) -> np.ndarray:
        return np.array([-2.0 * (p - pos[a]) @ wp for a, (p, _, wp, _) in enumerate(state(q))])

    def errors(q: np.ndarray) -> np.ndarray:
        return np.array([rotation_angle(rot[a], r) for a, (_, r, _, _) in enumerate(state(q))])

    start = np.clip(q0, lo, hi)
    best, best_errs = start, np.full(2, np.inf)
    # a start range per joint: its stops; one turn beyond the stop it has; a turn about 0 without
    draw_lo = np.where(np.isfinite(lo), lo, np.where(np.isfinite(hi), hi - 2 * np.pi, -np.pi))
    draw_hi = np.where(np.isfinite(hi), hi, np.where(np.isfinite(lo), lo + 2 * np.pi, np.pi))
    for s in [start, *(rng.uniform(draw_lo, draw_hi) for _ in range(seeds))]:
        res = minimize(
            objective,
            s,
            jac=True,
            method="SLSQP",
            bounds=list(zip(lo, hi)),
            constraints=[{"type": "ineq", "fun": within, "jac": within_jac}],
            options={"maxiter": 200, "ftol": 1e-10},
        )
        if np.all(within(res.x) >= -1e-6) and np.sum(e := errors(res.x)) < np.sum(best_errs):
            best, best_errs = res.x, e
    return best, (best_errs if np.all(np.isfinite(best_errs)) else errors(start))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    floor_arguments(parser, "armar3,armar6,dual_panda")
    parser.add_argument("--every", type=int, default=10)
    parser.add_argument("--tol", type=float, default=0.01)
    parser.add_argument("--widen", default="")
    parser.add_argument("--seeds", type=int, default=0)
    args = parser.parse_args()
    takes = kit_takes(args.takes)
    print(
        f"{len(takes)} takes x {args.seconds:g} s, {args.approach}, every {args.every}th frame, "
        f"position within {args.tol * 100:g} cm; widened: {args.widen or 'none'}; "
        f"{args.seeds} random starts beside the solved frame"
    )
    print(f"{FLOOR_HEAD}  joints the floor leaves at a stop (share of frames)")
    for name in args.robots.split(","):
        robot = hlik.load_robot(name)
        widen = np.array([np.radians(90.0) if j in args.widen.split(",") else 0.0 for j in robot.joint_names])
        solved, floor, stops, rng = [], [], Counter(), np.random.default_rng(0)
        for _, res in solved_runs(name, args.approach, takes, args.seconds):
            traj, ev = res.trajectory, res.evaluation
            for t in range(0, traj.q.shape[0], args.every):
                q, errs = floor_pose(
                    robot,
                    traj.q[t],
                    traj.targets.pos[t],
                    traj.targets.rot[t],
                    args.tol,
                    widen,
                    args.seeds,
                    rng,
                )
                solved.append(ev.fori[t])
                floor.append(errs)
                at = (q - robot.lower < STOP_MARGIN + 1e-3) | (robot.upper - q < STOP_MARGIN + 1e-3)
                stops.update(j for j, hit in zip(robot.joint_names, at & (widen == 0)) if hit)
        s, f = np.degrees(np.concatenate(solved)), np.degrees(np.concatenate(floor))
        n = len(solved)
        bound = ", ".join(f"{j} {c / n * 100:.0f} %" for j, c in stops.most_common(4))
        row = (
            f"{np.median(s):6.1f} {np.percentile(s, 95):7.1f} {np.median(f):6.1f} {np.percentile(f, 95):8.1f}"
        )
        print(f"{name:10s} {row}  {bound}")


if __name__ == "__main__":
    main()
