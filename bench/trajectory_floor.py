"""How far the speed and acceleration limits, not the solver, keep the hands off their orientation.

``orientation_floor.py`` asks each frame alone what the joint ranges allow. Here the whole clip is
one problem: a sequential convex programme (OSQP, sparse) over every frame's configuration at once,
started from the solved run, that turns both TCPs toward their target orientations (least squares
of the rotation vectors) with each TCP within ``--tol`` of its target position, while the motion
keeps the stops less the solvers' stop margin, the joint speed limits and the acceleration limits
from frame to frame (finite differences at the run's rate). Torques, collisions, the first frame's
rest and every human-likeness criterion are left out: its errors show what those limits allow
near the run's branch of the arms (a local search, as ``orientation_floor.py``'s without seeds).
Below the run's, they are what looking ahead across the whole clip could buy; a solver that also
keeps the torques and collisions may get less of it.

Each iteration linearises the TCP poses at the current motion (Gauss-Newton), limits each joint's
change to a trust region, and keeps the step only if the clip's summed squared orientation error
falls, a hand further off than sqrt(3) ``--tol`` or than the run left it counted as
:data:`PENALTY` per m² (else the region halves). OSQP keeps the limits to its tolerance: each take's
line gives the largest speed and acceleration over their limits (up to 1.02 seen). The table: the
run's and the floor's median and 95th percentile of the hand orientation error (degrees), median
hand position error (cm) and the frames with a hand more than 1 cm off (%).

Run by hand: ``python bench/trajectory_floor.py [--robots armar3,dual_panda] [--approach
qp+SYN+HJA_r] [--takes 8] [--seconds 5] [--tol 0.003] [--iterations 20] [--time-scale 1]``: about
three minutes a take and robot.
"""

from __future__ import annotations

import argparse

import mujoco
import numpy as np
import osqp
import scipy.sparse as sp

import hlik
from common import FLOOR_HEAD, floor_arguments, kit_takes, solved_runs
from hlik.robot.model import SIDES
from hlik.util.spatial import rotation_angle, rotation_vector

STOP_MARGIN = np.radians(3.0)  # the solvers' default stop margin (QPSettings.stop_margin)
PENALTY = 1e5  # rad^2 per m^2: a hand 1 mm beyond its bound costs as much as 0.3 rad in one frame


class Clip:
    """The TCP poses and Jacobians of a robot over a clip, for the programme."""

    def __init__(self, robot: hlik.Robot, pos: np.ndarray, rot: np.ndarray) -> None:
        self.robot, self.pos, self.rot = robot, pos, rot  # (T, 2, 3), (T, 2, 3, 3) base frame
        self.data = mujoco.MjData(robot.model)
        self.sites = [robot.site_id(s, "tcp") for s in SIDES]

    def linearise(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Position errors (T, 2, 3) m, rotation vectors of R R*^T (T, 2, 3) rad, and their
        Jacobians (T, 2, 3, n) at the motion ``q`` (T, n)."""
        model, data = self.robot.model, self.data
        t_n, n = q.shape
        ep, eo = np.zeros((t_n, 2, 3)), np.zeros((t_n, 2, 3))
        jp, jo = np.zeros((t_n, 2, 3, model.nv)), np.zeros((t_n, 2, 3, model.nv))
        for t in range(t_n):
            data.qpos[:] = q[t]  # the models' qpos are the joints, in order (robots/README.md)
            mujoco.mj_kinematics(model, data)
            mujoco.mj_comPos(model, data)
            for a, s in enumerate(self.sites):
                mujoco.mj_jacSite(model, data, jp[t, a], jo[t, a], s)
                ep[t, a] = data.site_xpos[s] - self.pos[t, a]
                eo[t, a] = rotation_vector(data.site_xmat[s].reshape(3, 3) @ self.rot[t, a].T)
        return ep, eo, jp[..., :n], jo[..., :n]


def orientation_errors(clip: Clip, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(T, 2) orientation errors, rad, and (T, 2) position errors, m, of the motion ``q``."""
    ep, eo, _, _ = clip.linearise(q)
    return np.linalg.norm(eo, axis=-1), np.linalg.norm(ep, axis=-1)


def floor_motion(
    robot: hlik.Robot,
    q0: np.ndarray,
    clip: Clip,
    dt: float,
    tol: float,
    iterations: int,
    headroom: float = 1.0,
) -> np.ndarray:
    """(T, n) the motion near ``q0`` (T, n) with the least summed squared orientation error whose
    TCPs stay within ``tol`` m (per axis, linearised) of their targets, inside the stops less the
    margin, the speed limits and the acceleration limits at the time step ``dt`` s."""
    t_n, n = q0.shape
    lo = np.where(np.isinf(robot.lower), -1e3, robot.lower + STOP_MARGIN)
    hi = np.where(np.isinf(robot.upper), 1e3, robot.upper - STOP_MARGIN)
    q = np.clip(q0, lo, hi)
    v = np.where(np.isfinite(robot.velocity_limit), robot.velocity_limit, 1e3) * dt * headroom
    acc = np.where(np.isfinite(robot.acceleration_limit), robot.acceleration_limit, 1e4) * dt * dt * headroom
    d1 = sp.diags([-1.0, 1.0], [0, 1], shape=(t_n - 1, t_n))
    d2 = sp.diags([1.0, -2.0, 1.0], [0, 1, 2], shape=(t_n - 2, t_n))
    eye_n = sp.identity(n, format="csc")
    a_mat = sp.vstack([sp.identity(t_n * n), sp.kron(d1, eye_n), sp.kron(d2, eye_n)]).tocsc()
    region = np.radians(10.0)
    ep, eo, jp, jo = clip.linearise(q)  # re-linearised only where a step is taken
    # a hand further off than tol (as a distance) or than the start left it costs PENALTY per m^2
    # in the merit a step must lower: the linearised position rows alone let the hands drift
    reach = np.maximum(np.linalg.norm(ep, axis=-1), np.sqrt(3.0) * tol)
    cost = float(np.sum(np.linalg.norm(eo, axis=-1) ** 2))
    for _ in range(iterations):
        # least squares in dq: sum over frames and hands of |eo + jo dq|^2 + 1e-4 |dq|^2
        blocks = [sum(jo[t, a].T @ jo[t, a] for a in range(2)) + 1e-4 * np.eye(n) for t in range(t_n)]
        p_mat = sp.block_diag(blocks, format="csc")
        grad = np.concatenate([sum(jo[t, a].T @ eo[t, a] for a in range(2)) for t in range(t_n)])
        # position: within tol per axis after the step, linearised
        pos_rows = sp.block_diag([jp[t].reshape(6, n) for t in range(t_n)], format="csc")
        pos_err = ep.reshape(-1)
        flat = q.reshape(-1)
        vel = np.diff(q, axis=0).reshape(-1)
        accel = np.diff(q, 2, axis=0).reshape(-1)
        box_lo = np.maximum(np.tile(lo, t_n) - flat, -region)
        box_hi = np.minimum(np.tile(hi, t_n) - flat, region)
        a_all = sp.vstack([a_mat, pos_rows]).tocsc()
        l_all = np.concatenate(
            [box_lo, -np.tile(v, t_n - 1) - vel, -np.tile(acc, t_n - 2) - accel, -tol - pos_err]
        )
        u_all = np.concatenate(
            [box_hi, np.tile(v, t_n - 1) - vel, np.tile(acc, t_n - 2) - accel, tol - pos_err]
        )
        # a start whose hand is already beyond tol: that bound moves to where it is (the limits'
        # rows are not moved: the start keeps them, and so does every step)
        k = len(pos_err)
        l_all[-k:], u_all[-k:] = np.minimum(l_all[-k:], 0.0), np.maximum(u_all[-k:], 0.0)
        solver = osqp.OSQP()
        solver.setup(
            p_mat,
            grad,
            a_all,
            l_all,
            u_all,
            verbose=False,
            eps_abs=1e-6,
            eps_rel=1e-6,
            max_iter=20000,
            polishing=True,
        )
        res = solver.solve()
        if res.x is None or not np.all(np.isfinite(res.x)):
            region /= 2.0
            continue
        trial = q + res.x.reshape(t_n, n)
        at_trial = clip.linearise(trial)
        beyond = np.maximum(np.linalg.norm(at_trial[0], axis=-1) - reach, 0.0)
        trial_cost = float(np.sum(np.linalg.norm(at_trial[1], axis=-1) ** 2) + PENALTY * np.sum(beyond**2))
        if trial_cost < cost:
            q, cost, region = trial, trial_cost, min(region * 1.5, np.radians(30.0))
            ep, eo, jp, jo = at_trial
        else:
            region /= 2.0
        if region < 1e-5:
            break
    return q


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    floor_arguments(parser, "armar3,dual_panda")
    parser.add_argument("--tol", type=float, default=0.003, help="TCP position bound, m per axis")
    parser.add_argument("--iterations", type=int, default=20)
    parser.add_argument(
        "--time-scale", type=float, default=1.0, help="play each take this many times as long"
    )
    args = parser.parse_args()
    takes = kit_takes(args.takes)
    print(
        f"{len(takes)} takes x {args.seconds:g} s, {args.approach}, position within {args.tol * 100:g} cm "
        f"per axis, {args.iterations} iterations, time scale {args.time_scale:g}"
    )
    print(f"{FLOOR_HEAD} {'fPOS cm':>8s} {'floor':>6s} {'>1cm %':>7s} {'floor':>6s}")
    for name in args.robots.split(","):
        robot = hlik.load_robot(name)
        solved, floor, pos, run_pos = [], [], [], []
        for take, res in solved_runs(name, args.approach, takes, args.seconds, args.time_scale):
            traj = res.trajectory
            clip = Clip(robot, traj.targets.pos, traj.targets.rot)
            dt = float(np.median(np.diff(traj.times)))
            q = floor_motion(robot, traj.q, clip, dt, args.tol, args.iterations)
            ori, dist = orientation_errors(clip, q)
            solved.append(rotation_angle(traj.targets.rot, traj.tcp_rot))  # (T, 2)
            floor.append(ori)
            pos.append(dist)
            run_pos.append(np.linalg.norm(traj.tcp_pos - traj.targets.pos, axis=-1))
            speed = np.max(np.abs(np.diff(q, axis=0)) / dt / robot.velocity_limit)
            accel = np.max(np.abs(np.diff(q, 2, axis=0)) / dt**2 / robot.acceleration_limit)
            print(
                f"  {take.stem[:40]:40s} fORI {np.degrees(np.median(solved[-1])):5.1f} -> "
                f"{np.degrees(np.median(ori)):5.1f}, p95 {np.degrees(np.percentile(solved[-1], 95)):5.1f} -> "
                f"{np.degrees(np.percentile(ori, 95)):5.1f}; fPOS max {np.max(dist) * 100:.2f} cm; "
                f"speed {speed:.3f}, acceleration {accel:.3f} x limit"
            )
        s, f = np.degrees(np.concatenate(solved).ravel()), np.degrees(np.concatenate(floor).ravel())
        p, r = np.concatenate(pos) * 100, np.concatenate(run_pos) * 100  # (frames, 2) cm
        row = (
            f"{np.median(s):6.1f} {np.percentile(s, 95):7.1f} "
            f"{np.median(f):6.1f} {np.percentile(f, 95):8.1f} "
            f"{np.median(r):8.2f} {np.median(p):6.2f} {100 * np.mean(np.any(r > 1, axis=1)):7.1f} "
            f"{100 * np.mean(np.any(p > 1, axis=1)):6.1f}"
        )
        print(f"{name:10s} {row}")


if __name__ == "__main__":
    main()
