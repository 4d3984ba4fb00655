"""The tables ``hlik run`` prints: the run's summary, the controller's and the posture's rows."""

from __future__ import annotations

from rich.table import Table


def _frames(n: int) -> str:
    return f"{n} frame" if n == 1 else f"{n} frames"


def controller_line(c) -> str:
    """The summary's ``controller`` row: what :class:`hlik.executable.ControllerChecks` found."""
    j = c.to_json()
    parts = []
    if c.has_acceleration_limits:
        parts.append(
            f"peak acceleration {j['max_acceleration_ratio']:.2f} of its limit ({j['acceleration_joint']}), "
            f"{_frames(j['frames_over_acceleration'])} over, a joint at it in "
            f"{100 * j['share_at_acceleration_limit']:.1f} % of frames"
        )
    else:
        parts.append("no acceleration limits given")
    if c.has_jerk_limits:
        parts.append(
            f"peak jerk {j['max_jerk_ratio']:.2f} of its limit ({j['jerk_joint']}), "
            f"{_frames(j['frames_over_jerk'])} over"
        )
    else:
        parts.append(f"peak jerk {j['max_jerk']:.0f} rad/s³ ({j['jerk_joint']}; no jerk limits given)")
    if c.has_effort_limits:
        parts.append(
            f"peak torque {j['max_torque_ratio']:.2f} of its limit ({j['torque_joint']}, "
            f"{j['max_torque']:.1f} N m), {_frames(j['frames_over_effort'])} over"
        )
    else:
        parts.append(f"peak torque {j['max_torque']:.1f} N m ({j['torque_joint']}; no effort limits given)")
    parts.append(f"a joint within 0.5° of a stop in {100 * j['share_at_stop']:.1f} % of frames")
    if j["share_at_margin"] > 0.0:  # parked on the solvers' soft stop
        parts.append(
            f"within 3.5° (the solvers' margin) in {100 * j['share_at_margin']:.1f} % "
            f"({j['margin_joint']} in {100 * j['margin_joint_share']:.1f} %)"
        )
    parts.append(f"base at z {j['base_height']:.3f} m, lowest point {j['lowest_point']:.3f} m")
    if j["end_speed"] > 0.0:
        if j["stop_time"] is not None:
            stop = f"{j['stop_time']:.2f} s to stop at the acceleration limits"
        elif j["acceleration_limits"]:
            stop = "a joint without an acceleration limit among them"
        else:
            stop = "no acceleration limits given"
        parts.append(f"ends moving at up to {j['end_speed']:.2f} rad/s ({stop}; an export adds the braking)")
    else:
        parts.append("ends at rest")
    return "; ".join(parts)


def posture_line(p) -> str:
    """The summary's ``posture`` row: the robot's :class:`hlik.posture.Posture` beside the subject's
    (medians; lengths as shares of the arm's length; left / right)."""
    j = p.to_json()
    shown = lambda v, spec, unit="": "undefined" if v is None else f"{format(v, spec)}{unit}"  # noqa: E731
    pair = lambda key: " / ".join(shown(v, ".2f") for v in j[key])  # noqa: E731
    percent = lambda key: " / ".join(f"{100 * v:.0f} %" for v in j[key])  # noqa: E731
    return (
        f"trunk lean {j['trunk_lean_deg']:.0f}° (subject {j['subject_trunk_lean_deg']:.0f}°); "
        f"elbows in front of the shoulders {pair('elbow_front_share')} arm (subject "
        f"{pair('subject_elbow_front_share')}), > 5 cm behind in {percent('elbow_behind_share')} of frames "
        f"(subject {percent('subject_elbow_behind_share')}); hands in front {pair('hand_front_share')} arm "
        f"(subject {pair('subject_hand_front_share')}), wrists {pair('wrist_front_share')} "
        f"(subject {pair('subject_wrist_front_share')}); swivel off the subject's by "
        f"{' / '.join(shown(v, '.0f', '°') for v in j['swivel_difference_deg'])}; arm joint path "
        f"{j['path_ratio']:.2f} of the subject's"
    )


# what the summary's solver row and the recording's result panel say of each priority
PRIORITY = {
    "hands_first": "the hands first (hands_first: the criteria in their null space)",
    "preview_hands_first": "the look-ahead's path from the hands first (preview_hands_first)",
    "weighted": "weighted",
}


def run_summary(traj, motion, solve_time: float, ev, solver_note: str = "", beyond=None) -> Table:
    """The run's summary table, without the file names (printed after it, never wrapped);
    ``solver_note``: what the solver row adds (its priority and look-ahead), empty: nothing;
    ``beyond``: (T, 2) how far each hand's target lies beyond its arm's reach, m
    (:meth:`hlik.robot.reach.ArmReach.beyond`), for the lagging row."""
    import numpy as np

    from hlik.criteria.functional import relative_errors
    from hlik.findings import LAG, lag_spans
    from hlik.solvers import solver_spec

    fpos, fori = ev.fpos, ev.fori
    table = Table(show_header=False, box=None)
    table.add_column(no_wrap=True)
    table.add_column(overflow="fold")
    table.add_row("frames", f"{traj.n_frames} over {motion.duration:.2f} s at {motion.rate:.1f} Hz")
    p = traj.placement
    table.add_row(
        "placement",
        f"{p.method}: base at ({p.translation[0]:.2f}, {p.translation[1]:.2f}, {p.translation[2]:.2f}) m, "
        f"yaw {np.degrees(p.yaw):.0f}°",
    )
    table.add_row("solve time", f"{solve_time:.2f} s ({1e3 * solve_time / traj.n_frames:.3f} ms/frame)")
    d = traj.diagnostics
    table.add_row(
        "solver",
        f"{d.n_failed} failed, {d.n_unconverged} unconverged "
        f"({'roundoff' if solver_spec(traj.solver).name == 'slsqp' else 'iteration cap'}) of "
        f"{traj.n_frames} frames; median {np.median(d.iterations):.0f} iterations/frame"
        + (f"; {solver_note}" if solver_note else ""),
    )
    for i, side in enumerate(("left", "right")):
        deg = np.degrees(fori[:, i])
        table.add_row(
            f"{side} hand",
            f"fPOS mean {100 * fpos[:, i].mean():.1f} cm, max {100 * fpos[:, i].max():.1f} cm; "
            f"fORI mean {deg.mean():.1f}°, median {np.median(deg):.1f}°, "
            f"p95 {np.percentile(deg, 95):.1f}°, max {deg.max():.1f}°",
        )
    speed = ev.max_speed_ratio
    speeds = (
        f"joint speeds within their limits (at most {speed:.2f} of one)"
        if speed <= 1.0 + 1e-6
        else f"max joint speed {speed:.2f} x its limit"
    )
    table.add_row("body", f"{int(np.count_nonzero(ev.collisions))} frames in self-collision; {speeds}")
    table.add_row("controller", controller_line(ev.controller))
    table.add_row("posture", posture_line(ev.posture))
    lag = lag_spans(fpos, traj.times) if ev.scenario == "pose" else ""  # relative: no hand targets
    tracks = solver_spec(traj.solver).tracks_targets
    said = ""
    if beyond is not None and tracks and bool(np.any(beyond > 0.0)):
        said = (
            f"; a target beyond its arm's reach in {int(np.count_nonzero(beyond.any(axis=1)))} frames, up to "
            f"{100 * beyond.max():.1f} cm (tracked at the reach)"
        )
    if lag:
        reason = (
            f"{traj.solver} maps the joints and does not track the hands"
            if not tracks
            else "out of reach, too fast for the speed limits, or outweighed by the criteria"
        )
        table.add_row("lagging", f"hands > {100 * LAG:.0f} cm off their targets ({reason}): {lag}{said}")
    elif ev.scenario == "pose":  # said, so that a missing row is not taken for a missing check
        table.add_row(
            "lagging", f"none: no hand more than {100 * LAG:.0f} cm off its target in any frame{said}"
        )
    off_pos, off_rot = relative_errors(traj.tcp_pos, traj.tcp_rot, traj.targets.pos, traj.targets.rot)
    table.add_row(
        "hands relative",
        f"fPOS_off mean {100 * off_pos.mean():.1f} cm, fORI_off mean {np.degrees(off_rot.mean()):.1f}°",
    )
    return table
