"""The limits a robot controller checks, kept by every optimising solver in every frame.

Per joint, from the robot description (:class:`hlik.robot.model.Robot`): the position stops, the
speed, the acceleration and the effort (torque). Each frame's configuration ``q_t`` is bounded,
given the two previous solutions ``q1 = q_t-1``, ``q2 = q_t-2`` (``v1 = (q1 - q2) / dt``), by

- the position stops, |q_t - q1| <= v_max dt (speed), |q_t - 2 q1 + q2| <= a_max dt^2
  (acceleration) and, where the robot gives jerk limits and the frame before ``q3 = q_t-3`` is
  known, |(q_t - 2 q1 + q2) - (q1 - 2 q2 + q3)| <= j_max dt^3 (jerk): hard;
- a margin of ``stop_margin`` inside the stops, approached by braking: the speed toward the
  margin at distance D after the step may be at most sqrt(2 a_max D), which bounds the step in
  closed form (:func:`braking_speed`). From any state that kept these bounds, the next frame's
  bounds intersect (the braking speed falls by at most ``a_max dt`` per frame), so a joint is never
  driven into its stop, it decelerates before it. The margin holds even where the target needs the
  stop (the hand then lags by at most the margin's worth; ``stop_margin = 0`` gives the stops
  back). These bounds are soft only against the hard ones: where a state breaks them, the hard box
  wins and the joint returns as fast as the acceleration limit lets it;
- the joint torques, ``tau = M(q1) (q_t - 2 q1 + q2) / dt^2 + b(q1, v1)`` (inertia, gravity and
  Coriolis, as ``mujoco.mj_inverse`` computes them at q1 with the central-difference
  acceleration), within ``torque_fraction`` of the effort limits: linear rows on ``q_t``.

The box and the rows of a frame are a :class:`hlik.solvers.frames.JointBox`; the QP takes them as
its step bounds and inequalities (:class:`hlik.solvers.mink_ik.MinkSolver`, for ``qp`` and
``mink``), SLSQP as linear constraints, JV as the box its steps are scaled into (and rows of its
constrained step). Written once here, so that they cannot drift apart.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from hlik.robot.model import Robot
from hlik.solvers.settings import LimitSettings

# halvings of a frame's box finding how far a joint may go and still stop within its jerk limit
JERK_BISECTIONS = 20
# the share of the deceleration the acceleration limits could give a distance (|grad| @ a_max) that
# braking before a collision margin counts on: the rest is left to the other rows (stops, torques)
# and to the pair's normal turning as it closes
BRAKING_SHARE = 0.5
# the deceleration, m/s^2, a pair closing fast is assumed to brake at when deciding how far ahead to
# look for it: below what the bundled arms give a hand pair at the braking share (2-Panda ~5,
# ARMAR-6 ~15), so that it is found before its braking distance
HORIZON_DECELERATION = 2.0


@dataclass(frozen=True, eq=False)
class Braking:
    """How far a distance between two bodies may close in a frame so that it can still stop at its
    margin: the frame's start ``previous`` (n,) (q_t-1, rad) and the frame before it ``before``
    (q_t-2), the joints' ``acceleration`` limits (n,), rad/s^2, and the frame's ``dt``, s."""

    previous: np.ndarray
    before: np.ndarray
    acceleration: np.ndarray
    dt: float

    def horizon(self, closing: np.ndarray, margin: float, detect: float) -> np.ndarray:
        """(p,) how far, m, to look for each pair closing by at most ``closing`` (p,), m, in the
        last frame: ``detect``, or farther for a fast pair, its braking distance at
        :data:`HORIZON_DECELERATION` and two frames' travel beyond the margin."""
        speed = closing / self.dt
        return np.maximum(detect, margin + 2.0 * closing + speed * speed / (2.0 * HORIZON_DECELERATION))

    def floors(self, distance: np.ndarray, gradient: np.ndarray, margin: float) -> np.ndarray:
        """The least distance (k,), m, that each of k distances (k,) at :attr:`previous`, with
        gradients (k, n) there, may reach at the end of the frame: the approach from which it can
        still stop at ``margin`` decelerating at :data:`BRAKING_SHARE` of ``|gradient| @ a_max``
        (v^2 <= 2 a (d - margin), as the joints brake before their stops). ``-inf`` for a
        distance moved by a joint without an acceleration limit. Less 0.1 mm: a distance no joint
        changes (coaxial capsules) would else be held to itself within rounding, infeasibly."""
        grad = np.abs(gradient)
        finite = np.isfinite(self.acceleration)
        deceleration = BRAKING_SHARE * (grad @ np.where(finite, self.acceleration, 0.0))
        deceleration[grad @ ~finite > 0] = np.inf
        return distance - self.dt * braking_speed(distance - margin, deceleration, self.dt) - 1e-4


@dataclass(frozen=True, eq=False)
class JointBox:
    """Bounds (n,) each on a frame's configuration, rad (infinite for unlimited joints), and
    optional linear rows on it, ``rows @ q <= bound`` ((k, n), (k,); the torque limits).

    ``braking``: how far the frame's distances between bodies may close, so that the solvers
    brake before the collision margin as before the stops (None without acceleration limits).
    """

    lower: np.ndarray
    upper: np.ndarray
    rows: np.ndarray | None = None
    bound: np.ndarray | None = None
    braking: Braking | None = None

    def step_rows(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The rows as bounds on a step ``dq`` from ``q``: (k, n), (k,) (k = 0 without rows)."""
        if self.rows is None or self.bound is None:
            return np.zeros((0, len(q))), np.zeros(0)
        return self.rows, self.bound - self.rows @ q

    def clip(self, q: np.ndarray) -> np.ndarray:
        return np.minimum(np.maximum(q, self.lower), self.upper)  # half np.clip's time on (n,)

    def step_bounds(self, q: np.ndarray, max_step: float) -> tuple[np.ndarray, np.ndarray]:
        """Bounds (n,) each on a step from ``q`` into the box, at most ``max_step`` per joint; a
        joint outside the box may only move back (0 is always allowed)."""
        lower = np.minimum(np.maximum(self.lower - q, -max_step), 0.0)
        upper = np.maximum(np.minimum(self.upper - q, max_step), 0.0)
        return lower, upper


@dataclass(frozen=True, eq=False)
class MotionLimits:
    """A robot's per-joint limits as the frame loop applies them; arrays (n,).

    Attributes:
        robot: The robot (its model gives the torques).
        lower, upper: The position stops, rad (``-inf``/``inf`` for unlimited joints).
        inner_lower, inner_upper: The stops moved in by the margin, rad.
        velocity: Speed limits, rad/s.
        acceleration: Acceleration limits, rad/s^2 (``inf``: none).
        jerk: Jerk limits, rad/s^3 (``inf``: none).
        effort: Torque limits allowed to the solvers, N m (``inf``: none).
    """

    robot: Robot
    lower: np.ndarray
    upper: np.ndarray
    inner_lower: np.ndarray
    inner_upper: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    jerk: np.ndarray
    effort: np.ndarray

    @classmethod
    def of(cls, robot: Robot, settings: object = None) -> MotionLimits:
        """The limits ``settings`` (a :class:`LimitSettings`, or a solver's settings; default
        :class:`LimitSettings`) keep on ``robot``."""
        s = settings if isinstance(settings, LimitSettings) else LimitSettings()
        margin = np.minimum(s.stop_margin, 0.2 * (robot.upper - robot.lower))
        margin = np.where(np.isfinite(margin), margin, 0.0)
        accel = robot.acceleration_limit if s.acceleration_limits else np.full(robot.dof, np.inf)
        jerk = robot.jerk_limit if s.acceleration_limits else np.full(robot.dof, np.inf)
        effort = s.torque_fraction * robot.effort_limit if s.torque_limits else np.full(robot.dof, np.inf)
        return cls(
            robot,
            robot.lower,
            robot.upper,
            robot.lower + margin,
            robot.upper - margin,
            robot.velocity_limit,
            accel,
            jerk,
            effort,
        )

    @property
    def has_torque(self) -> bool:
        return bool(np.any(np.isfinite(self.effort)))

    def box(
        self,
        q1: np.ndarray | None,
        q2: np.ndarray | None,
        dt: float,
        data: mujoco.MjData | None = None,
        q3: np.ndarray | None = None,
    ):
        """The :class:`~hlik.solvers.frames.JointBox` of the frame after ``q1`` (n,), ``q2`` (n,)
        and ``q3`` (n,) (the previous solutions, newest first; ``q1`` None: the first frame, the
        stops only; ``q3`` None: no jerk bound)."""
        if q1 is None:  # the start: anywhere inside the margin
            return JointBox(self.inner_lower, self.inner_upper)
        q2 = q1 if q2 is None else q2
        v1 = (q1 - q2) / dt
        a = self.acceleration
        reach = self.velocity * dt
        coast = q1 + v1 * dt
        speed_lo, speed_hi = np.maximum(self.lower, q1 - reach), np.minimum(self.upper, q1 + reach)
        with np.errstate(invalid="ignore"):
            hard_lo = np.maximum(speed_lo, np.where(np.isfinite(a), coast - a * dt * dt, -np.inf))
            hard_hi = np.minimum(speed_hi, np.where(np.isfinite(a), coast + a * dt * dt, np.inf))
        # a state outside the hard box (a start beyond a stop) keeps at least the speed box
        bad = hard_lo > hard_hi
        hard_lo = np.where(bad, speed_lo, hard_lo)
        hard_hi = np.where(bad, speed_hi, hard_hi)
        # inside the margin: brake before it; in it (a start on a stop): back out of it
        soft_hi = np.minimum(q1 + dt * braking_speed(self.inner_upper - q1, a, dt), self.inner_upper)
        soft_lo = np.maximum(q1 - dt * braking_speed(q1 - self.inner_lower, a, dt), self.inner_lower)
        lower = np.minimum(np.maximum(soft_lo, hard_lo), hard_hi)
        upper = np.maximum(np.minimum(np.maximum(soft_hi, hard_lo), hard_hi), lower)
        if q3 is not None and np.any(np.isfinite(self.jerk)):
            # the acceleration within the jerk limit of the last frame's, and no more toward the
            # speed limit than the jerk limit can take back before it (the speed's braking, as the
            # position's before the stops). It gives way where the box above leaves it no room:
            # the stops and the acceleration limit come first, the jerk check reports the overrun
            last = (q1 - 2.0 * q2 + q3) / (dt * dt)
            with np.errstate(invalid="ignore"):
                j_lo = np.maximum(last - self.jerk * dt, -braking_speed(self.velocity + v1, self.jerk, dt))
                j_hi = np.minimum(last + self.jerk * dt, braking_speed(self.velocity - v1, self.jerk, dt))
                jerk_lo = np.maximum(lower, np.where(np.isfinite(j_lo), coast + j_lo * dt * dt, -np.inf))
                jerk_hi = np.minimum(upper, np.where(np.isfinite(j_hi), coast + j_hi * dt * dt, np.inf))
            # and before the stops' margin, braking as the jerk lets it: the acceleration turns
            # round at j_max first, so it brakes earlier than at a_max alone
            up = self._jerk_braking(jerk_lo, jerk_hi, q1, q2, dt, self.inner_upper - q1)
            down = self._jerk_braking(-jerk_hi, -jerk_lo, -q1, -q2, dt, q1 - self.inner_lower)  # mirrored
            jerk_lo, jerk_hi = np.maximum(jerk_lo, -down), np.minimum(jerk_hi, up)
            keep = jerk_lo <= jerk_hi
            lower, upper = np.where(keep, jerk_lo, lower), np.where(keep, jerk_hi, upper)
        rows = bound = None
        available = a
        if self.has_torque:
            rows, bound, spare = self.torque_rows(q1, q2, dt, data)
            # bodies brake at what the joints can give within their efforts too: the G1's 25 N m
            # shoulders reach far less than their 40 rad/s^2 with the arm out
            available = np.minimum(a, spare)
        braking = Braking(q1, q2, available, dt) if np.any(np.isfinite(available)) else None
        return JointBox(lower, upper, rows, bound, braking)

    def _jerk_braking(
        self, lo: np.ndarray, hi: np.ndarray, q1: np.ndarray, q2: np.ndarray, dt: float, room: np.ndarray
    ) -> np.ndarray:
        """(n,) the largest ``q_t`` in [lo, hi] (n,) from which each joint, moving up from ``q1``,
        ``q2`` (n,) with ``room`` (n,) rad left before its stop's margin, can still stop before it
        within its acceleration and jerk limits (:func:`jerk_stop_distance`, a frame late); ``lo``
        where none can, ``inf`` for a joint without a stop or a jerk limit. Bisection: the distance
        grows with ``q_t``."""
        out = np.full(len(q1), np.inf)
        active = np.isfinite(room) & np.isfinite(self.jerk) & np.isfinite(self.acceleration)
        if not active.any():
            return out
        start = q1 + room  # the margin, in q
        out[active] = np.minimum(hi[active], start[active])

        def keeps(q: np.ndarray, j: np.ndarray) -> np.ndarray:  # q (k,) of the joints j (k,)
            v = (q - q1[j]) / dt
            acc = (q - 2.0 * q1[j] + q2[j]) / (dt * dt)
            stop = jerk_stop_distance(v, acc, self.acceleration[j], self.jerk[j])
            return start[j] - q - v * dt - stop >= 0.0

        joints = np.flatnonzero(active)
        bind = joints[~keeps(out[joints], joints)]  # most frames: no joint near enough to brake
        low, high = lo[bind], out[bind]
        for _ in range(JERK_BISECTIONS if len(bind) else 0):
            mid = 0.5 * (low + high)
            inside = keeps(mid, bind)
            low, high = np.where(inside, mid, low), np.where(inside, high, mid)
        out[bind] = low
        return out

    def torque_rows(
        self, q1: np.ndarray, q2: np.ndarray, dt: float, data: mujoco.MjData | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Rows (2k, n) and bounds (2k,), ``rows @ q_t <= bound``: the torques of the k joints with
        an effort limit, at q1 with the acceleration ``(q_t - 2 q1 + q2) / dt^2``, within it; and
        (n,) the acceleration each joint has alone within its effort, rad/s^2 (what is left of
        the effort beside gravity and Coriolis, over the joint's own inertia; ``inf`` without an
        effort limit)."""
        model = self.robot.model
        data = mujoco.MjData(model) if data is None else data
        data.qpos[:], data.qvel[:] = q1, (q1 - q2) / dt
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        mujoco.mj_crb(model, data)
        mujoco.mj_comVel(model, data)
        mujoco.mj_rne(model, data, 0, data.qfrc_bias)
        inertia = full_inertia(model, data)
        idx = np.flatnonzero(np.isfinite(self.effort))
        m = inertia[idx] / (dt * dt)
        offset = data.qfrc_bias[idx] - m @ (2.0 * q1 - q2)  # tau = m q_t + offset
        effort = self.effort[idx]
        available = np.full(len(q1), np.inf)
        spare = np.maximum(effort - np.abs(data.qfrc_bias[idx]), 0.0)
        available[idx] = spare / np.maximum(np.diag(inertia)[idx], 1e-9)
        return np.vstack([m, -m]), np.concatenate([effort - offset, effort + offset]), available


def jerk_stop_distance(v: np.ndarray, a: np.ndarray, a_max: np.ndarray, j_max: np.ndarray) -> np.ndarray:
    """(n,) how far a joint still travels, rad, with speed ``v`` (n,) and acceleration ``a`` (n,)
    toward a stop, braking time-optimally within ``a_max`` and ``j_max`` (n,): its acceleration
    turns round at ``j_max`` until the speed is 0 or the deceleration ``a_max``, then holds it.
    0 for a joint that never moves toward the stop."""
    disc = a * a + 2.0 * j_max * v
    t_stop = (a + np.sqrt(np.maximum(disc, 0.0))) / j_max  # the speed is 0 while turning round
    t_turn = np.maximum(a + a_max, 0.0) / j_max  # the deceleration reaches a_max
    turning = v * t_stop + 0.5 * a * t_stop**2 - j_max * t_stop**3 / 6.0
    v_turn = v + a * t_turn - 0.5 * j_max * t_turn**2
    holding = v * t_turn + 0.5 * a * t_turn**2 - j_max * t_turn**3 / 6.0 + v_turn**2 / (2.0 * a_max)
    away = (disc < 0.0) | (t_stop < 0.0)  # its speed toward the stop never turns positive again
    return np.where(away, 0.0, np.maximum(np.where(t_stop <= t_turn, turning, holding), 0.0))


def braking_speed(distance: np.ndarray, acceleration: np.ndarray, dt: float) -> np.ndarray:
    """The largest speed v (n,) toward a stop ``distance`` (n,) away (m or rad, before the step)
    such that after a step of ``v dt`` the joint can still stop in front of it decelerating at
    ``acceleration`` (n,): ``v^2 <= 2 a (distance - v dt)``, solved for v. 0 at or past the stop;
    ``inf`` without an acceleration limit or a stop."""
    d = np.maximum(distance, 0.0)
    with np.errstate(invalid="ignore"):
        v = -acceleration * dt + np.sqrt(np.square(acceleration * dt) + 2.0 * acceleration * d)
    return np.where(np.isfinite(acceleration) & np.isfinite(d), v, np.inf)


def full_inertia(model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    """(nv, nv) the joint-space inertia matrix of the configuration ``data`` holds (after
    ``mj_crb``), with the armature."""
    out = np.empty((model.nv, model.nv))
    try:
        mujoco.mj_fullM(model, data, out)  # MuJoCo 4
    except TypeError:
        mujoco.mj_fullM(model, out, data.qM)  # MuJoCo 3
    return out
