"""Posture measures of a trajectory beside the paper's metrics: how the robot's trunk, elbows and hands
sit against its shoulders, each against the subject's own value at the same frame.

Both bodies are measured in their own frames, z up: the robot in its base frame, the subject in the
world. The **frontal plane** contains both shoulders and the vertical; its normal f, horizontal, points
forward (``f = z × (shoulder_right − shoulder_left)``, normalised,
:func:`hlik.human.kinematics.shoulder_axes`; x right, y forward, z up). With
S the shoulders' midpoint and L an arm's length (shoulder to elbow plus elbow to wrist):

- **trunk lean** (rad, forward positive): the trunk axis' angle from the vertical in the plane of f
  and z, ``atan2(a · f, a · z)``. The subject's axis runs from the pelvis (the MMM root) to S; the
  robot's is the vertical carried by the body that holds its shoulders, ``R(q) R(home)ᵀ z`` (the hip
  of ARMAR-III; 0 for a fixed torso);
- **elbow front** (m, per arm): the elbow's offset from the frontal plane, ``(elbow − S) · f``;
  negative behind the back;
- **hand front** (m, per arm): the TCP's distance in front of the shoulders, ``(tcp − S) · f``;
- **wrist front** (m, per arm): the wrist's, ``(wrist − S) · f``. The robots' hands are long for
  their arms (wrist to TCP 0.24 L on ARMAR-III, 0.27 L on ARMAR-6, 0.32 L on a Panda, the subject's
  0.16 L), so a robot whose TCP is on the subject's has its TCP further ahead of its shoulders in
  arm lengths than the subject's even where its arm is posed like the subject's: the wrist is
  where the arm's posture shows, the TCP where the task does;
- **swivel** (rad, per arm): the elbow's angle about the shoulder–wrist axis
  (:func:`hlik.criteria.eea.swivel_angle`, Kim et al.'s Ψ; NaN where singular);
- **path ratio**: the arm joints' path over the take, ``Σ_t Σ_j |Δq_j|``, over the mapped human
  pose's (the JM configuration ``q_map``) on the same joints: below 1 the arms move less than the
  person, above more.

Lengths are compared as fractions of L (the robot's at home, the subject's median), so a robot of
another size is compared with the subject scaled to it. Reported, not part of m_hl.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hlik.criteria.angles import joint_difference
from hlik.human.kinematics import arm_length as arm_lengths
from hlik.human.kinematics import forward_kinematics, shoulder_axes
from hlik.human.swivel import swivel_angle
from hlik.robot.model import Robot
from hlik.trajectory import Trajectory
from hlik.util.spatial import site_poses

BEHIND = 0.05  # m: an elbow this far behind the frontal plane is "behind the back"
UP = np.array([0.0, 0.0, 1.0])


@dataclass(frozen=True, eq=False)
class BodyPosture:
    """One body's posture measures per frame (see the module): arrays (T,) or (T, 2) (arm 0 =
    left), and ``arm_length`` (2,), m."""

    lean: np.ndarray
    elbow_front: np.ndarray
    hand_front: np.ndarray
    wrist_front: np.ndarray
    swivel: np.ndarray
    arm_length: np.ndarray

    @property
    def elbow_front_share(self) -> np.ndarray:
        """(T, 2) the elbow front over the arm's length."""
        return self.elbow_front / self.arm_length

    @property
    def hand_front_share(self) -> np.ndarray:
        """(T, 2) the hand front over the arm's length."""
        return self.hand_front / self.arm_length

    @property
    def wrist_front_share(self) -> np.ndarray:
        """(T, 2) the wrist front over the arm's length."""
        return self.wrist_front / self.arm_length

    @property
    def elbow_behind(self) -> np.ndarray:
        """(T, 2) True where the elbow is more than :data:`BEHIND` behind the frontal plane."""
        return self.elbow_front < -BEHIND


@dataclass(frozen=True, eq=False)
class Posture:
    """The robot's and the subject's :class:`BodyPosture` and the arm joints' path ratio."""

    robot: BodyPosture
    subject: BodyPosture
    path_ratio: float

    def to_json(self) -> dict:
        """The ``"posture"`` object of ``hlik evaluate --json``: medians over the frames, angles in
        degrees, shares of frames in [0, 1]; per arm [left, right], ``None`` where no frame defines
        the value (an arm straight throughout has no swivel)."""
        r, s = self.robot, self.subject

        def arms(x: np.ndarray) -> list[float | None]:  # None (null) where no frame defines it (swivel)
            finite = [c[np.isfinite(c)] for c in x.T]
            return [float(np.median(c)) if len(c) else None for c in finite]

        return {
            "trunk_lean_deg": float(np.degrees(np.median(r.lean))),
            "subject_trunk_lean_deg": float(np.degrees(np.median(s.lean))),
            "trunk_lean_difference_deg": float(np.degrees(np.median(np.abs(r.lean - s.lean)))),
            "elbow_front_share": arms(r.elbow_front_share),
            "subject_elbow_front_share": arms(s.elbow_front_share),
            "elbow_behind_share": [float(v) for v in np.mean(r.elbow_behind, axis=0)],
            "subject_elbow_behind_share": [float(v) for v in np.mean(s.elbow_behind, axis=0)],
            "hand_front_share": arms(r.hand_front_share),
            "subject_hand_front_share": arms(s.hand_front_share),
            "hand_front_ratio": arms(r.hand_front_share / s.hand_front_share),
            "wrist_front_share": arms(r.wrist_front_share),
            "subject_wrist_front_share": arms(s.wrist_front_share),
            "wrist_front_ratio": arms(r.wrist_front_share / s.wrist_front_share),
            "swivel_difference_deg": arms(np.degrees(np.abs(wrap(r.swivel - s.swivel)))),
            "path_ratio": self.path_ratio,
        }


def wrap(angle: np.ndarray) -> np.ndarray:
    """Angles in (-pi, pi]."""
    return np.pi - np.mod(np.pi - angle, 2.0 * np.pi)


def body_posture(
    shoulder: np.ndarray,
    elbow: np.ndarray,
    wrist: np.ndarray,
    tcp: np.ndarray,
    trunk: np.ndarray,
    arm_length: np.ndarray | None = None,
) -> BodyPosture:
    """The measures of a body from its joint centres (T, 2, 3) each, arm 0 = left, z up, and its
    trunk axis (T, 3) (any length, pointing up the trunk); ``arm_length`` (2,), m: default the
    median over the frames."""
    mid = shoulder.mean(axis=1)  # (T, 3)
    _, front = shoulder_axes(shoulder[:, 0], shoulder[:, 1])
    lean = np.arctan2(np.einsum("ti,ti->t", trunk, front), trunk @ UP)
    if arm_length is None:
        arm_length = np.median(arm_lengths(shoulder, elbow, wrist), axis=0)
    return BodyPosture(
        lean=lean,
        elbow_front=np.einsum("tai,ti->ta", elbow - mid[:, None], front),
        hand_front=np.einsum("tai,ti->ta", tcp - mid[:, None], front),
        wrist_front=np.einsum("tai,ti->ta", wrist - mid[:, None], front),
        swivel=swivel_angle(shoulder, elbow, wrist),
        arm_length=np.asarray(arm_length, dtype=float),
    )


def robot_posture(robot: Robot, q: np.ndarray) -> BodyPosture:
    """The :class:`BodyPosture` of ``robot`` at configurations ``q`` (T, n), in its base frame."""
    ids = robot.site_ids[:, :4]  # (2, 4): shoulder, elbow, wrist, TCP
    pos, rot = site_poses(robot.model, q, ids)  # one kinematics pass: (T, 2, 4, 3), (T, 2, 4, 3, 3)
    home, rot_home = site_poses(robot.model, robot.home[None], ids)
    length = arm_lengths(home[0, :, 0], home[0, :, 1], home[0, :, 2])
    trunk = rot[:, 0, 0] @ (rot_home[0, 0, 0].T @ UP)  # the vertical at home, carried by the shoulders' body
    return body_posture(pos[:, :, 0], pos[:, :, 1], pos[:, :, 2], pos[:, :, 3], trunk, length)


def subject_posture(traj: Trajectory) -> BodyPosture:
    """The subject's :class:`BodyPosture` over ``traj``'s motion, in the world."""
    human = forward_kinematics(traj.motion)
    trunk = human.shoulder.mean(axis=1) - traj.motion.root_position
    return body_posture(human.shoulder, human.elbow, human.wrist, human.tcp_pos, trunk)


def path_ratio(traj: Trajectory, robot: Robot) -> float:
    """The arm joints' path of ``traj`` over that of the mapped human pose (NaN if the human's
    arms do not move)."""
    arms = [robot.joint_names.index(j) for side in robot.arm_joints.values() for j in side]
    unlimited = np.isinf(robot.lower[arms])
    own = np.abs(joint_difference(traj.q[1:, arms], traj.q[:-1, arms], unlimited)).sum()
    mapped = traj.reference.q_map[:, arms]
    human = np.abs(joint_difference(mapped[1:], mapped[:-1], unlimited)).sum()
    return float(own / human) if human > 0 else float("nan")


def posture(traj: Trajectory, robot: Robot) -> Posture:
    """The :class:`Posture` measures of ``traj`` on ``robot``."""
    return Posture(robot_posture(robot, traj.q), subject_posture(traj), path_ratio(traj, robot))


__all__ = ["BodyPosture", "Posture", "body_posture", "posture", "robot_posture", "subject_posture"]
