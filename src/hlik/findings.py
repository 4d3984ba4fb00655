"""What a user should know about a retargeted trajectory, in one line each: hands off their targets
or turned away, failed and capped frames, self-collision and the limits a controller checks
exceeded (from the evaluation), and the spans where the hands lag. ``hlik run`` prints them.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from hlik.criteria.functional import relative_errors
from hlik.executable import BELOW_FLOOR, ControllerChecks
from hlik.human.motion import HumanMotion, stretches
from hlik.metrics import Evaluation
from hlik.solvers import solver_spec
from hlik.trajectory import Trajectory

LAG = 0.05  # m: a hand this far off its target is reported as lagging
STOP_SHARE = 0.05  # a joint on a stop in more frames than this is warned about
OFF_SHARE = 0.10  # a hand further than LAG from its target in more frames than this is warned about
LOW_RATE = 50.0  # Hz below which --rate 0 is warned about: the criteria's constants assume 100 Hz
TURNED = 30.0  # degrees: a hand turned this far from its target's orientation is warned about
# degrees: a hand whose median orientation error is above this is warned about, however it spreads
# (ARMAR-6's SLSQP left hand on the whole Cut take: 17 deg median, never 30 deg for 10 % of frames)
TURNED_MEDIAN = 10.0


def run_warnings(traj: Trajectory, motion: HumanMotion, ev: Evaluation, rate: float) -> list[str]:
    """One line for each thing the user should know about ``traj`` retargeted from ``motion``
    (resampled to ``rate`` Hz; 0: at its own rate) and evaluated as ``ev``."""
    n = traj.n_frames
    share = lambda k: f"{k} of {n} frames ({100 * k / n:.0f} %)"  # noqa: E731
    notes = []
    # jm maps the joint angles: by design it neither tracks the hands nor keeps the speed and
    # acceleration limits (the summary says how far off it is); warning on every jm run would bury
    # the real warnings. Torques, stops and the floor are warned about for every solver.
    tracking = solver_spec(traj.solver).tracks_targets

    def often(err: np.ndarray, limit: float) -> int:
        """Frames of ``err`` (T,) above ``limit``, if a tracking solver has more than OFF_SHARE; else 0."""
        k = int(np.count_nonzero(err > limit))
        return k if tracking and k > OFF_SHARE * n else 0

    if ev.scenario == "relative":  # the hands follow their relative pose, not the human's hands
        gap = relative_errors(traj.tcp_pos, traj.tcp_rot, traj.targets.pos, traj.targets.rot)[0]
        if off := often(gap, LAG):
            notes.append(
                f"the hands' relative position is more than {100 * LAG:.0f} cm off the human's in "
                f"{share(off)}, up to {100 * gap.max():.1f} cm (fPOS_off)"
            )
    else:
        fpos, fori = ev.fpos, np.degrees(ev.fori)
        for i, side in enumerate(("left", "right")):
            if off := often(fpos[:, i], LAG):
                notes.append(
                    f"{side} hand more than {100 * LAG:.0f} cm off its target in {share(off)}, up to "
                    f"{100 * fpos[:, i].max():.1f} cm (out of reach, or too fast for the speed limits)"
                )
        for i, side in enumerate(("left", "right")):
            if off := often(fori[:, i], TURNED):
                notes.append(
                    f"{side} hand turned more than {TURNED:.0f}° from its target in {share(off)}, up to "
                    f"{fori[:, i].max():.0f}° (out of reach, or traded for the criteria)"
                )
            elif tracking and (typical := float(np.median(fori[:, i]))) > TURNED_MEDIAN:
                notes.append(
                    f"{side} hand turned {typical:.0f}° from its target's orientation (median), "
                    f"{np.percentile(fori[:, i], 95):.0f}° in its worst 5 % of frames (beyond the "
                    "joints' ranges, or traded for the criteria: raise orientation_cost)"
                )
    if low := below_floor(traj):
        notes.append(low)
    if rate == 0 and motion.rate < LOW_RATE:
        notes.append(
            f"--rate 0 keeps the motion's {motion.rate:g} Hz; the criteria's constants assume 100 Hz "
            "(the paper's): consider --rate 100"
        )
    d = traj.diagnostics
    if d.n_failed:
        notes.append(f"the solver failed in {share(d.n_failed)}")
    if d.n_unconverged:
        why = "iteration cap, or SLSQP's roundoff limit"
        notes.append(f"the solver stopped before converging ({why}) in {share(d.n_unconverged)}")
    touching = int(np.count_nonzero(ev.collisions))
    if touching:
        notes.append(f"the robot is in self-collision in {share(touching)}")
    c, too_fast = ev.controller, ev.max_speed_ratio > 1.0 + 1e-6
    if tracking and too_fast:
        notes.append(f"joint speeds exceed their limits, at most {ev.max_speed_ratio:.2f} x the limit")
    if not tracking and (too_fast or c.frames_over_acceleration):
        # one line, not one per limit: a mapping baseline is not for a robot, and a new user
        # running the default solver should hear it
        over = [f"{ev.max_speed_ratio:.2f} x a speed limit"] if too_fast else []
        if c.frames_over_acceleration:
            frames = share(c.frames_over_acceleration)
            over.append(f"{c.acceleration_ratio.max():.2f} x an acceleration limit in {frames}")
        notes.append(
            f"{traj.solver} maps the joint angles and keeps no speed or acceleration limit: up to "
            f"{', '.join(over)}; not for a robot as it is (hlik export refuses it; --solver qp keeps "
            "the limits)"
        )
    return notes + controller_warnings(c, tracking, share)


def below_floor(traj: Trajectory) -> str:
    """A line naming the hand targets below the robot's floor (world z = 0, the height its base
    stands at), or ``""``. No hand can follow them there: the subject stooped lower than the
    robot's placement allows, or the scaling to the robot's arms lowered them (a subject scaled
    down about its shoulders)."""
    z = traj.placement.to_world(traj.targets.pos)[..., 2]  # (T, 2)
    low = z < -BELOW_FLOOR
    if not low.any():
        return ""
    k, side = np.unravel_index(np.argmin(z), z.shape)
    frames = int(np.count_nonzero(low.any(axis=1)))
    return (
        f"the hand targets go below the floor in {frames} of {traj.n_frames} frames, down to "
        f"{z[k, side]:.2f} m ({('left', 'right')[side]}, {traj.times[k]:.2f} s): the subject reaches lower "
        "than the robot can (a stoop, or the scaling to its arms); no hand can follow them there"
    )


def controller_warnings(c: ControllerChecks, tracking: bool, share: Callable[[int], str]) -> list[str]:
    """One ``warning:`` line for each limit :class:`ControllerChecks` ``c`` finds exceeded."""
    j, notes = c.to_json(), []
    if tracking and c.frames_over_acceleration:
        notes.append(
            f"joint accelerations exceed their limits in {share(c.frames_over_acceleration)}, at most "
            f"{j['max_acceleration_ratio']:.2f} x the limit ({j['acceleration_joint']})"
        )
    if tracking and c.frames_over_jerk:
        notes.append(
            f"joint jerks exceed their limits in {share(c.frames_over_jerk)}, at most "
            f"{j['max_jerk_ratio']:.2f} x the limit ({j['jerk_joint']})"
        )
    if c.frames_over_effort:
        notes.append(
            f"joint torques exceed their effort limits in {share(c.frames_over_effort)}, at most "
            f"{j['max_torque_ratio']:.2f} x the limit ({j['torque_joint']}, {j['max_torque']:.0f} N m)"
        )
    if c.share_at_stop > STOP_SHARE:
        notes.append(
            f"a joint is within 0.5° of a stop in {share(int(j['frames_at_stop']))} "
            "(a controller keeps a margin)"
        )
    if c.lowest_point < -BELOW_FLOOR:
        notes.append(f"the robot reaches {100 * -c.lowest_point:.1f} cm below the floor")
    return notes


def lag_spans(fpos: np.ndarray, times: np.ndarray, shown: int = 3) -> str:
    """The time spans where either hand is more than :data:`LAG` off its target, e.g.
    ``"1.50-3.52 s (left), 4.00-4.20 s (both); 203 frames"``; empty if none.

    Args:
        fpos: (T, 2) position errors of the hands, m.
        times: (T,) frame times, s.
    """
    off = fpos > LAG  # (T, 2)
    any_off = off.any(axis=1)
    if not any_off.any():
        return ""
    spans = []
    for start, stop in stretches(any_off):
        left, right = bool(off[start:stop, 0].any()), bool(off[start:stop, 1].any())
        which = "both" if left and right else ("left" if left else "right")
        when = f"{times[start]:.2f}" if stop - start == 1 else f"{times[start]:.2f}-{times[stop - 1]:.2f}"
        spans.append(f"{when} s ({which})")
    more = f", {len(spans) - shown} more" if len(spans) > shown else ""
    n = int(any_off.sum())
    return f"{', '.join(spans[:shown])}{more}; {n} frame{'s' if n != 1 else ''}"
