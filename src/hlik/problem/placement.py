"""Where the robot stands in the human's world: a rigid transform ``world <- robot base``.

Every rule stands the robot on the human's floor (world z = 0): the base is upright (a yaw about
the vertical) at the robot's own height, :func:`hlik.robot.floor.floor_height` (0 for a model that
follows the convention of robots/README.md, its floor at z = 0 of the base frame), and a rule
chooses only x, y and yaw (``Robot.placement`` names each robot's default). A robot smaller than
the subject is not sunk to the subject's shoulders: the subject is scaled to it
(``subject_scale``, :mod:`hlik.problem.scale`).

- ``shoulders``: the midpoint of the robot's shoulders on the human's at the first frame, facing the
  same way (heading from the shoulder line, so a slouch or a turned pelvis does not tilt the robot).
- ``reach`` (the paper's, Sec. IV-A): inversion of the robot's oriented reachability maps for every
  left- and right-hand pose of the motion (Vahrenkamp et al. 2013; formulas.md §7): each candidate
  base pose (x, y, yaw) scores the minimum map entry over all hand poses, the scores are mean
  filtered, and the best candidate wins.
- ``mapped``: where the joint-mapped human pose puts the robot's hands on the human's (a
  least-squares fit over the frames that agree on the place, found by consensus).
- ``working``: among the base poses ``reach`` scores at least :data:`WORKING_REACH` of its best, the
  one that puts the hands where the subject works: in front of and beside the shoulders by the
  subject's median distances as shares of the arm's length (:func:`working_placement`).
- ``X,Y,YAW``: given by the user (:func:`placement_from_spec`); ``X,Y,YAW,Z`` also gives the base
  height, off the floor (:func:`placement_notes` says so). ``optimize``, which retargets from
  several of these, lives in :mod:`hlik.placement_search` (it needs a solver).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import uniform_filter

from hlik.human.kinematics import (
    HumanKinematics,
    arm_length,
    forward_kinematics,
    shoulder_axes,
    shoulder_frame,
)
from hlik.human.motion import HumanMotion
from hlik.robot.floor import FLOOR_TOLERANCE, floor_height
from hlik.robot.model import SIDES, Robot, joint_mapping, tcp_poses
from hlik.robot.reachability import ReachabilityMap, reachability_map
from hlik.util.errors import SettingsError
from hlik.util.spatial import site_poses, yaw_rotation

PLACEMENTS = ("reach", "mapped", "working", "shoulders")
# the share of the best reach score a base pose of ``working`` must keep: the hands stay well inside
# the reachability maps while the distance to them follows the subject's
WORKING_REACH = 0.5


@dataclass(frozen=True, eq=False)
class Placement:
    """The pose of the robot base in the world.

    Attributes:
        rotation: (3, 3) world <- base rotation.
        translation: (3,) base origin in the world, metres.
    """

    rotation: np.ndarray
    translation: np.ndarray
    method: str = "given"

    @property
    def matrix(self) -> np.ndarray:
        """(4, 4) homogeneous world <- base transform."""
        m = np.eye(4)
        m[:3, :3] = self.rotation
        m[:3, 3] = self.translation
        return m

    @classmethod
    def from_matrix(cls, matrix: np.ndarray, method: str = "given") -> Placement:
        matrix = np.asarray(matrix, dtype=float)
        return cls(matrix[:3, :3].copy(), matrix[:3, 3].copy(), method)

    @property
    def yaw(self) -> float:
        """Heading of the base x axis about the world z axis, rad."""
        return float(np.arctan2(self.rotation[1, 0], self.rotation[0, 0]))

    def to_world(self, pos: np.ndarray, rot: np.ndarray | None = None):
        """Base-frame positions (..., 3) (and rotations (..., 3, 3)) expressed in the world."""
        p = pos @ self.rotation.T + self.translation
        return p if rot is None else (p, self.rotation @ rot)

    def to_base(self, pos: np.ndarray, rot: np.ndarray | None = None):
        """World positions (..., 3) (and rotations (..., 3, 3)) expressed in the robot base frame."""
        p = (pos - self.translation) @ self.rotation
        return p if rot is None else (p, self.rotation.T @ rot)


def shoulder_placement(robot: Robot, human: HumanKinematics) -> Placement:
    """Shoulder midpoints coincide at the first frame seen from above, both facing the same way;
    robot at home, standing on the floor (its shoulders at their own height, not the human's)."""
    ids = np.array([robot.site_id(s, "shoulder") for s in SIDES])
    pos, _ = site_poses(robot.model, robot.home[None], ids)
    r_rob, o_rob = shoulder_frame(pos[0, 0], pos[0, 1])
    r_hum, o_hum = shoulder_frame(human.shoulder[0, 0], human.shoulder[0, 1])
    rotation = r_hum @ r_rob.T
    translation = o_hum - rotation @ o_rob
    translation[2] = floor_height(robot)
    return Placement(rotation, translation, "shoulders")


def placement_notes(robot: Robot, placement: Placement) -> list[str]:
    """A note if the base is not at the robot's floor height (``X,Y,YAW,Z``): it does not stand on
    the floor."""
    height, floor = float(placement.translation[2]), floor_height(robot)
    if abs(height - floor) <= FLOOR_TOLERANCE:
        return []
    where = "above" if height > floor else "below"
    return [
        f"placement {placement.method}: {robot.title} does not stand on its floor: its base is at "
        f"z = {height:.3f} m, {abs(height - floor):.3f} m {where} the height it stands at ({floor:.3f} m)"
    ]


@dataclass(frozen=True)
class ReachSearch:
    """The candidate grid of :func:`reach_placement`, around the motion: offsets of the base along
    the axes of the shoulder placement, from the mean hand position, and yaws from its heading.

    Attributes:
        step: Grid step of the base position, m.
        radius: Half-width of the square of base positions, m.
        yaw_step: Grid step of the base yaw, rad (the whole circle is searched).
        n_targets: Frames of the motion whose hand poses are inverted (evenly spaced over the
            frames where the take is; all if fewer).
        filter_size: Width of the mean filter in grid cells (x, y and yaw).
    """

    step: float = 0.05
    radius: float = 1.2
    yaw_step: float = np.radians(10.0)
    n_targets: int = 100
    filter_size: int = 3


def reach_placement(
    robot: Robot,
    human: HumanKinematics,
    reach: ReachabilityMap | None = None,
    search: ReachSearch = ReachSearch(),
) -> Placement:
    """The paper's placement: the base pose where the worst-reachable hand pose of the motion is
    best reachable (minimum over both hands' ORM entries, mean filtered, arg-max).

    Where no candidate reaches every hand pose, the poses that even the best candidate misses are
    left out of the minimum (the k smallest entries are skipped, k the fewest any candidate
    misses): a stretch of unreachable targets then does not decide where the robot stands. The
    search is carried in the motion's own frame, so moving or turning the whole motion
    moves the placement with it.
    """
    score, offsets, yaws, frame = reach_scores(robot, human, reach, search)
    k, i = np.unravel_index(int(np.argmax(score)), score.shape)
    r0, c0 = frame
    rotation = yaw_rotation(yaws[k]) @ r0
    return Placement(rotation, c0 + r0 @ offsets[i], "reach")


def _target_frames(human: HumanKinematics, search: ReachSearch) -> np.ndarray:
    """(N,) indices of the frames of ``human`` whose hand poses the candidate grid is scored on:
    ``search.n_targets`` evenly spaced over the frames where the take is (:func:`_consensus` on
    the shoulders' midpoint, a tenth of the take a window; every frame of a take that stays in one
    place). A stretch carried away is no place to stand for (README "Placement")."""
    where = human.shoulder[:, :, :2].mean(axis=1)  # (T, 2)
    kept = np.flatnonzero(_consensus(where, max(1, len(where) // 10)))
    return kept[np.unique(np.linspace(0, len(kept) - 1, search.n_targets).astype(int))]


def _in_candidates(
    pos: np.ndarray, c0: np.ndarray, r0: np.ndarray, yaw: float, offsets: np.ndarray
) -> np.ndarray:
    """(m, N, 2, 3) hand positions ``pos`` (N, 2, 3, world) in the base frames of the candidates at
    ``offsets`` (m, 3) of the search frame (``r0``, ``c0``) turned by ``yaw``."""
    local = (pos - c0) @ (yaw_rotation(yaw) @ r0)  # from the search origin, candidate axes
    shift = offsets @ yaw_rotation(yaw)  # candidate origins in their own axes: Rz(-yaw) offset
    return local[None] - shift[:, None, None]


def reach_scores(
    robot: Robot,
    human: HumanKinematics,
    reach: ReachabilityMap | None = None,
    search: ReachSearch = ReachSearch(),
) -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple[np.ndarray, np.ndarray]]:
    """Filtered placement scores over the candidate grid of ``search``.

    Returns:
        (n_yaw, n_xy) scores; (n_xy, 3) base offsets in the search frame, m; (n_yaw,) yaws, rad;
        and the search frame: (3, 3) rotation (the shoulder placement's) and (3,) origin (mean hand
        position, at the robot's floor height).
    """
    reach = reach or reachability_map(robot)
    start = shoulder_placement(robot, human)
    r0 = start.rotation
    frames = _target_frames(human, search)
    pos, rot = human.tcp_pos[frames], human.tcp_rot[frames]  # (N, 2, 3), (N, 2, 3, 3)
    c0 = np.array([*pos.reshape(-1, 3).mean(axis=0)[:2], floor_height(robot)])
    g = np.arange(-search.radius, search.radius + 1e-9, search.step)
    gx, gy = np.meshgrid(g, g, indexing="ij")
    offsets = np.stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)], axis=-1)
    yaws = np.arange(0.0, 2 * np.pi - 1e-9, search.yaw_step)
    ranked = np.empty((len(yaws), len(offsets), 2 * len(frames)), dtype=np.uint16)
    for k, yaw in enumerate(yaws):
        r = yaw_rotation(yaw) @ r0  # world <- candidate base
        base_rot = np.einsum("ji,nsjk->nsik", r, rot)
        hands = _in_candidates(pos, c0, r0, yaw, offsets)
        entries = np.concatenate(
            [reach.lookup(s, hands[:, :, s], base_rot[None, :, s]) for s in range(2)], axis=1
        )
        ranked[k] = np.sort(entries, axis=1)
    # The paper's minimum over all hand poses; where no candidate reaches them all, the minimum over
    # all but the fewest any candidate misses (so those do not flatten every score to 0).
    missed = int(np.min(np.count_nonzero(ranked == 0, axis=2)))
    score = ranked[:, :, min(missed, ranked.shape[2] - 1)].astype(float)
    n = len(g)
    score = uniform_filter(
        score.reshape(len(yaws), n, n), search.filter_size, mode=("wrap", "nearest", "nearest")
    )
    return score.reshape(len(yaws), -1), offsets, yaws, (r0, c0)


def working_distances(
    shoulder: np.ndarray, elbow: np.ndarray, wrist: np.ndarray, tcp: np.ndarray
) -> np.ndarray:
    """(..., 2) the hands' median distance in front of and beside the shoulders' midpoint (toward
    each hand's own side), as shares of the arm's length, from joint centres (..., T, 2, 3) each,
    z up (medians over the frames and both arms)."""
    mid = shoulder.mean(axis=-2)
    across, front = shoulder_axes(shoulder[..., 0, :], shoulder[..., 1, :])
    length = np.median(arm_length(shoulder, elbow, wrist), axis=(-2, -1))
    rel = tcp - mid[..., None, :]
    ahead = np.einsum("...tai,...ti->...ta", rel, front)
    side = np.einsum("...tai,...ti->...ta", rel, across) * np.array([-1.0, 1.0])  # outward positive
    return (
        np.stack([np.median(ahead, axis=(-2, -1)), np.median(side, axis=(-2, -1))], axis=-1)
        / length[..., None]
    )


def working_placement(
    robot: Robot,
    human: HumanKinematics,
    reach: ReachabilityMap | None = None,
    search: ReachSearch = ReachSearch(),
) -> Placement:
    """The base pose among those :func:`reach_scores` rates at least :data:`WORKING_REACH` of the
    best that puts the motion's hands at the subject's working distances
    (:func:`working_distances`: ahead of and beside the shoulders, per arm length), the robot's
    measured from its shoulders at home; ties go to the better reach score.

    ``reach`` alone stands a robot where its arms have the most room, which for ARMAR-6 was its
    hands at 0.9 of its arm's length in front of its shoulders against the subject's 0.6: arms
    stretched and elbows lifted."""
    score, offsets, yaws, (r0, c0) = reach_scores(robot, human, reach, search)
    subject = working_distances(human.shoulder, human.elbow, human.wrist, human.tcp_pos)
    home, _ = site_poses(robot.model, robot.home[None], robot.site_ids[:, :3])  # shoulder, elbow, wrist
    pos = human.tcp_pos[_target_frames(human, search)]  # (N, 2, 3)
    best = (np.inf, -np.inf, 0, 0)
    good = score >= WORKING_REACH * score.max()
    for k, yaw in enumerate(yaws):
        if not good[k].any():
            continue
        hands = _in_candidates(pos, c0, r0, yaw, offsets[good[k]])  # (m, N, 2, 3)
        shoulder, elbow, wrist = (np.broadcast_to(home[0, :, i], hands.shape) for i in range(3))
        miss = np.sum(np.abs(working_distances(shoulder, elbow, wrist, hands) - subject), axis=-1)
        j = int(np.argmin(miss - 1e-6 * score[k, good[k]]))
        i = int(np.flatnonzero(good[k])[j])
        if (miss[j], -score[k, i]) < (best[0], -best[1]):
            best = (float(miss[j]), float(score[k, i]), k, i)
    _, _, k, i = best
    return Placement(yaw_rotation(yaws[k]) @ r0, c0 + r0 @ offsets[i], "working")


def mapped_placement(robot: Robot, motion: HumanMotion, human: HumanKinematics | None = None) -> Placement:
    """Where the human's own joint angles put the robot's hands on the human's: the upright base
    pose that best fits the TCP positions of the joint mapping (JM, base frame) onto the human hand
    positions (world), both hands (2D Procrustes), over the frames that agree.

    Robust to stretches of unreachable targets (a subject carried away, ramps included). With the
    yaw of a fit over all frames (then, a second time, over the frames agreed on), each frame's
    offset (the mean over its hands of where the human hand is less where the mapped one lands)
    is what the translation would be for that frame alone; each :data:`MAPPED_WINDOW` of the take
    proposes the median of its frames' offsets, and the earliest proposal that at least
    :data:`MAPPED_SHARE` as many frames agree with (within :func:`_agreement`) as with the most
    agreed-with one wins (a consensus, as RANSAC's). The least-squares fit over the frames that
    agree with it, hand by hand with those farther than twice the median distance (and 5 cm) left
    out, three times over, is the placement: on a take that stays in one place, the plain fit. The
    fit over all frames it replaces stood the robot between the two places of a take carried 2 m
    away for 60 % of its frames, every hand off (field case unreachable_forward_2m). The robot stands
    on the floor, as with the other rules.
    """
    human = human or forward_kinematics(motion)
    mapped, _ = tcp_poses(robot, joint_mapping(robot, motion))
    a, b = mapped[..., :2], human.tcp_pos[..., :2]  # (T, 2 hands, 2)
    keep = np.ones(len(a), dtype=bool)
    every = max(1, int(round(MAPPED_WINDOW * motion.rate)))
    for _ in range(2):  # the yaw of all frames (a window's alone is ill-conditioned), then the agreed's
        yaw, _ = _procrustes(a[keep].reshape(-1, 2), b[keep].reshape(-1, 2))
        keep = _consensus(np.mean(b - a @ yaw_rotation(yaw)[:2, :2].T, axis=1), every)  # (T, 2) offsets
    # then within the agreeing frames, hand by hand, as the plain fit did over all of them: hand
    # positions farther from the fit than twice the median distance (and 5 cm) left out
    agreed = np.repeat(keep, 2)
    a, b = a.reshape(-1, 2), b.reshape(-1, 2)
    keep = agreed
    for _ in range(3):
        yaw, xy = _procrustes(a[keep], b[keep])
        miss = np.linalg.norm(a @ yaw_rotation(yaw)[:2, :2].T + xy - b, axis=-1)
        keep = agreed & (miss <= max(2.0 * float(np.median(miss[agreed])), 0.05))
    return Placement(yaw_rotation(yaw), np.array([xy[0], xy[1], floor_height(robot)]), "mapped")


# mapped_placement's consensus: each window of this many seconds proposes a translation, and the
# earliest that at least this share of the most agreed-with one's frames agree with wins: where the
# take starts (the field cases: a subject carried away, or drifting until the arms stretch, is
# reached for, not followed), unless the subject only passes through there (a walk to the table)
MAPPED_WINDOW = 1.0
MAPPED_SHARE = 0.5
# m: a subject who moves less stays in one place. At 0.4, on each of the eight KIT takes,
# and each robot stands exactly where the plain fit stood it; at 0.2 2-Panda's mapped hands, far
# from the human's, drifted out of agreement between a take's first and last second, and the fit
# over part of the Cut take turned it 7 deg (its m_hl 0.700 -> 0.679)
MAPPED_RADIUS = 0.4


def _consensus(points: np.ndarray, every: int) -> np.ndarray:
    """(N,) the frames that agree on where the take is: each window of ``every`` frames of
    ``points`` (N, 2), m, proposes its median, and the frames within :func:`_agreement` of the
    earliest proposal that at least :data:`MAPPED_SHARE` as many frames agree with as with the most
    agreed-with one (a consensus, as RANSAC's)."""
    windows = [points[k : k + every] for k in range(0, len(points), every)]
    proposals = [np.median(w, axis=0) for w in windows]
    radius = _agreement(windows, proposals)
    agree = [np.linalg.norm(points - p, axis=-1) <= radius for p in proposals]
    counts = np.array([np.count_nonzero(k) for k in agree])
    return agree[int(np.flatnonzero(counts >= MAPPED_SHARE * counts.max())[0])]


def _agreement(windows: list[np.ndarray], proposals: list[np.ndarray]) -> float:
    """How far, m, a frame's offset may be from a translation and agree with it: three times the
    median distance of a window's offsets from its own proposal (the spread of a take that stays
    in one place: a stretch carried away does not widen it), at least :data:`MAPPED_RADIUS`."""
    spread = np.median([np.median(np.linalg.norm(w - p, axis=-1)) for w, p in zip(windows, proposals)])
    return max(3.0 * float(spread), MAPPED_RADIUS)


def _procrustes(a: np.ndarray, b: np.ndarray) -> tuple[float, np.ndarray]:
    """The yaw (rad) and translation (2,) that best map the points ``a`` (N, 2) onto ``b``."""
    a_mean, b_mean = a.mean(axis=0), b.mean(axis=0)
    h = (a - a_mean).T @ (b - b_mean)
    yaw = float(np.arctan2(h[0, 1] - h[1, 0], h[0, 0] + h[1, 1]))
    return yaw, b_mean - yaw_rotation(yaw)[:2, :2] @ a_mean


def placement_from_spec(
    spec: str, robot: Robot, motion: HumanMotion, human: HumanKinematics | None = None
) -> Placement:
    """The placement named by ``spec``: ``reach``, ``mapped``, ``shoulders``, ``X,Y,YAW`` (world
    metres and degrees about z; standing on the floor) or ``X,Y,YAW,Z`` (and the base height, m:
    off the floor unless Z is :func:`~hlik.robot.floor.floor_height`; :func:`placement_notes` warns).

    Raises:
        SettingsError: anything else.
    """
    spec = spec.strip()
    human = human or forward_kinematics(motion)
    if spec == "reach":
        return reach_placement(robot, human)
    if spec == "mapped":
        return mapped_placement(robot, motion, human)
    if spec == "working":
        return working_placement(robot, human)
    if spec == "shoulders":
        return shoulder_placement(robot, human)
    try:
        values = [float(v) for v in spec.split(",")]
        if len(values) not in (3, 4):
            raise ValueError
    except ValueError:
        raise SettingsError(
            f"placement {spec!r}: expected one of {', '.join(PLACEMENTS)}, X,Y,YAW (m, m, deg), "
            "X,Y,YAW,Z (and the base height, m) or, in hlik run, optimize (hlik.placement_search in Python)"
        ) from None
    x, y, yaw = values[:3]
    height = values[3] if len(values) == 4 else floor_height(robot)
    return Placement(yaw_rotation(np.radians(yaw)), np.array([x, y, height]), spec)
