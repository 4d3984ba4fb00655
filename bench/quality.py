"""Quality table: robot x approach -> m_hl, m_f, m_hl,f and median fPOS on the recorded KIT takes.

An approach is a solver with the criteria it adds, e.g. ``jm``, ``qp``, ``qp+SYN``, ``jv+HJA_r``
(``+whole``: its result then optimised over the whole take, ``hlik run --whole-take``; ``+alone``:
without, ``--no-whole-take``; neither: as the stack chooses for the robot, as ``hlik run`` does),
``slsqp+SYN+HJA_r``. The stack (weights) is ``tasks/ee_pose.toml`` or ``tasks/relative_pose.toml``
(``--scenario``), or ``--stack``. Each take is cropped to ``--seconds`` after skipping the first second.
``fPOS reach`` is the median over frames whose target lies within 95 % of the arm's length from the
robot's shoulder (the frames the robot can reach); ``--placement`` the rule placing the robot
(``reach``, ``mapped``, ``working``, ``optimize``, ``shoulders``, ``X,Y,YAW``; default the robot's);
``capped %`` the share of frames that ended at the solver's iteration cap; ``speed`` the largest
joint speed over its limit in any step (any take) and ``contact %`` the share of frames in
self-collision. What a controller checks (:mod:`hlik.executable`): ``acc`` the largest joint
acceleration over its limit, ``acc>%`` the share of frames above an acceleration limit, ``tau`` the
largest torque over its effort limit, ``tau>%`` the frames above one, ``stop %`` the frames with a
joint within 0.5 deg of a stop, ``floor cm`` the lowest point of the robot against the floor (worst
take), ``lag %`` the frames with a hand more than 5 cm off, ``fORI`` (``fORI95``) the median (95th
percentile) hand orientation error in degrees. Posture (:mod:`hlik.posture`, medians over the
takes): ``lean`` the trunk lean's median difference from the subject's in degrees, ``behind %`` the
frames with an elbow more than 5 cm behind the shoulders' frontal plane (either arm; ``subj %`` the
subject's), ``hands`` the hands' distance in front of the shoulders over the subject's (per arm
length), ``wrists`` the same for the wrists, ``swivel`` the elbows' swivel angle off the subject's
(degrees, median over the frames, mean over the arms), ``path`` the arm joints' path over the mapped human
pose's. ``still`` the hands' mean speed in cm/s while their targets move slower than 2 cm/s: a hand
that swings about a target standing still (a tracker ringing after it caught up). An approach
``solver@stack+...`` takes its weights from that stack (``slsqp@paper_opt``).

Run by hand: ``python bench/quality.py [--robots armar3,armar6] [--approaches qp,qp+SYN]
[--set criterion_cost=0.1]`` (``--set`` overrides a field of the solvers' settings; ``--set
acceleration_limits=false --set torque_limits=false --set stop_margin=0`` gives the solvers
without the limits of ``solvers/limits.py``, for their cost).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import hlik
from common import kit_takes
from hlik.criteria.functional import position_error, relative_errors, rotation_angle
from hlik.criteria.learned import learn
from hlik.pipeline import RunSpec
from hlik.pipeline import run as run_pipeline
from hlik.robot.state import robot_state

DEFAULT = "jm,jv,qp,qp+SYN,qp+HJA_r,slsqp,slsqp+SYN,slsqp+HJA_r"
STILL = 0.02  # m/s: a target this slow stands still for the ``still`` column


def _setting(text: str) -> bool | int | float:
    """A ``--set`` value: true/false, an integer or a float."""
    if text.lower() in ("true", "false"):
        return text.lower() == "true"
    return int(text) if text.isdigit() else float(text)


def reachable(robot: hlik.Robot, traj: hlik.Trajectory) -> np.ndarray:
    """(T, 2) True where the hand target is within 95 % of the arm's reach of the shoulder."""
    home = robot_state(robot, robot.home).sites[0, :, :4]  # shoulder, elbow, wrist, TCP
    reach = np.sum(np.linalg.norm(np.diff(home, axis=1), axis=-1), axis=-1)  # (2,)
    shoulder = robot_state(robot, traj.q).shoulder
    return np.linalg.norm(traj.targets.pos - shoulder, axis=-1) < 0.95 * reach


def run(
    robot_name: str,
    approach: str,
    scenario: str,
    takes: list[Path],
    seconds: float,
    overrides: dict,
    placement: str | None = None,
    stack_name: str | None = None,
    scale: str | None = None,
    time_scale: float = 1.0,
) -> dict:
    robot = hlik.load_robot(robot_name)
    solver, *criteria = approach.split("+")
    # the solver's result then optimised over the whole take, or not; None: the stack's choice
    whole = True if "whole" in criteria else False if "alone" in criteria else None
    criteria = [c for c in criteria if c not in ("whole", "alone")]
    solver, _, own_stack = solver.partition("@")
    stack_name = own_stack or stack_name or ("relative_pose" if scenario == "relative" else "ee_pose")
    learned = learn(robot)
    rows, fpos, freach, off, times, capped, speed, contact = [], [], [], [], [], [], [], []
    acc, acc_over, tau, tau_over, stop, floor, fori = [], [], [], [], [], [], []
    lean, behind, subject_behind, hands, wrists, path, swivel, still = [], [], [], [], [], [], [], []
    for take in takes:
        spec = RunSpec(
            motion=take,
            robot=robot_name,
            solver=solver,
            stack=stack_name,
            criteria=tuple(criteria),
            scenario=scenario,
            placement=placement,
            scale=scale,
            span=(1.0, 1.0 + seconds),
            time_scale=time_scale,
            settings=overrides,
            whole_take=whole,
        )
        result = run_pipeline(spec, robot=robot, learned=learned)
        traj, ev = result.trajectory, result.evaluation
        times.append(result.solve_seconds / traj.n_frames)
        capped.append(~traj.diagnostics.converged)
        err = position_error(traj.tcp_pos, traj.targets.pos)
        rows.append((ev.m_hl, ev.m_f, ev.m_hl_f))
        speed.append(ev.max_speed_ratio)
        contact.append(ev.collisions)
        c = ev.controller
        acc.append(c.acceleration_ratio.max(initial=0.0))
        acc_over.append(c.acceleration_ratio > 1.0 + 1e-6)
        tau.append(c.torque_ratio.max(initial=0.0))
        tau_over.append(c.torque_ratio > 1.0 + 1e-6)
        stop.append(c.at_stop)
        floor.append(c.lowest_point)
        fori.append(rotation_angle(traj.tcp_rot, traj.targets.rot).ravel())
        pj = ev.posture.to_json()
        lean.append(pj["trunk_lean_difference_deg"])
        behind.append(ev.posture.robot.elbow_behind.any(axis=1))
        subject_behind.append(ev.posture.subject.elbow_behind.any(axis=1))
        hands.append(np.nanmean(np.array(pj["hand_front_ratio"], dtype=float)))  # None: nan
        wrists.append(np.nanmean(np.array(pj["wrist_front_ratio"], dtype=float)))
        path.append(pj["path_ratio"])
        swivel.append(np.nanmean(np.array(pj["swivel_difference_deg"], dtype=float)))
        target_speed = np.linalg.norm(np.diff(traj.targets.pos, axis=0), axis=-1) / traj.period
        hand_speed = np.linalg.norm(np.diff(traj.tcp_pos, axis=0), axis=-1) / traj.period
        still.append(hand_speed[target_speed < STILL])
        fpos.append(err.ravel())
        freach.append(err[reachable(robot, traj)])
        off.append(relative_errors(traj.tcp_pos, traj.tcp_rot, traj.targets.pos, traj.targets.rot)[0])
    m = np.mean(rows, axis=0)
    return {
        "m_hl": m[0],
        "m_f": m[1],
        "m_hl_f": m[2],
        "fpos": np.median(np.concatenate(fpos)),
        "freach": np.median(np.concatenate(freach)),
        "fpos_off": np.median(np.concatenate(off)),
        "ms": 1e3 * np.median(times),
        "capped": 100 * np.mean(np.concatenate(capped)),
        "speed": max(speed),
        "contact": 100 * np.mean(np.concatenate(contact)),
        "acc": max(acc),
        "acc_over": 100 * np.mean(np.concatenate(acc_over)),
        "tau": max(tau),
        "tau_over": 100 * np.mean(np.concatenate(tau_over)),
        "stop": 100 * np.mean(np.concatenate(stop)),
        "floor": 100 * max(floor, key=abs),
        "lag": 100 * np.mean(np.concatenate([np.any(e.reshape(-1, 2) > 0.05, axis=1) for e in fpos])),
        "fori": np.degrees(np.median(np.concatenate(fori))),
        "fori95": np.degrees(np.percentile(np.concatenate(fori), 95)),
        "lean": float(np.median(lean)),
        "behind": 100 * np.mean(np.concatenate(behind)),
        "subj_behind": 100 * np.mean(np.concatenate(subject_behind)),
        "hands": float(np.median(hands)),
        "wrists": float(np.median(wrists)),
        "path": float(np.median(path)),
        "swivel": float(np.median(swivel)),
        "still": 100 * float(np.mean(np.concatenate(still))) if np.concatenate(still).size else np.nan,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", default="armar3,armar6,dual_panda")
    parser.add_argument("--approaches", default=DEFAULT)
    parser.add_argument("--scenario", default="pose", choices=("pose", "relative"))
    parser.add_argument("--stack", default=None, help="task stack (default: ee_pose or relative_pose)")
    parser.add_argument("--seconds", type=float, default=5.0)
    parser.add_argument("--placement", default=None, help="reach, mapped, optimize, shoulders or X,Y,YAW")
    parser.add_argument("--takes", type=int, default=8, help="use the first N takes")
    parser.add_argument("--scale", default=None, help="subject scale: auto or a factor (default the robot's)")
    parser.add_argument("--set", action="append", default=[], help="override a setting: name=value")
    parser.add_argument(
        "--time-scale", type=float, default=1.0, help="play each take this many times as long"
    )
    args = parser.parse_args()
    overrides = {k: _setting(v) for k, v in (item.split("=", 1) for item in args.set)}
    takes = kit_takes(args.takes)
    where = args.placement or "the robot's"
    scale = args.scale or "the robot's"
    print(
        f"{len(takes)} takes x {args.seconds:g} s, scenario {args.scenario}, placement {where}, "
        f"scale {scale}, played {args.time_scale:g} times as long"
    )
    head = f"{'robot':11s} {'approach':18s} {'m_hl':>6s} {'m_f':>6s} {'m_hl,f':>6s} "
    cols = (
        ("fPOS cm", 8),
        ("reach cm", 8),
        ("off cm", 7),
        ("ms/frame", 8),
        ("capped %", 8),
        ("speed", 6),
        ("contact %", 9),
        ("acc", 5),
        ("acc>%", 5),
        ("tau", 5),
        ("tau>%", 5),
        ("stop %", 6),
        ("floor cm", 8),
        ("lag %", 5),
        ("fORI", 5),
        ("fORI95", 6),
        ("lean", 5),
        ("behind %", 8),
        ("subj %", 6),
        ("hands", 5),
        ("wrists", 6),
        ("path", 5),
        ("swivel", 6),
        ("still", 5),
    )
    print(head + " ".join(f"{name:>{width}s}" for name, width in cols), flush=True)
    for robot_name in args.robots.split(","):
        for approach in args.approaches.split(","):
            where = args.placement
            r = run(
                robot_name,
                approach,
                args.scenario,
                takes,
                args.seconds,
                overrides,
                where,
                args.stack,
                args.scale,
                args.time_scale,
            )
            print(
                f"{robot_name:11s} {approach:18s} {r['m_hl']:6.3f} {r['m_f']:6.3f} {r['m_hl_f']:6.3f} "
                f"{100 * r['fpos']:8.2f} {100 * r['freach']:8.2f} {100 * r['fpos_off']:7.2f} {r['ms']:8.2f} "
                f"{r['capped']:8.1f} {r['speed']:6.2f} {r['contact']:9.1f} {r['acc']:5.2f} "
                f"{r['acc_over']:5.1f} {r['tau']:5.2f} {r['tau_over']:5.1f} {r['stop']:6.1f} "
                f"{r['floor']:8.2f} {r['lag']:5.1f} {r['fori']:5.1f} {r['fori95']:6.1f} {r['lean']:5.1f} "
                f"{r['behind']:8.1f} {r['subj_behind']:6.1f} {r['hands']:5.2f} {r['wrists']:6.2f} "
                f"{r['path']:5.2f} {r['swivel']:6.1f} {r['still']:5.2f}",
                flush=True,
            )


if __name__ == "__main__":
    main()
