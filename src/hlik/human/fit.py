"""Fitting the MMM model to arm keypoints: from joint positions to the MMM joint angles hlik retargets.

Per frame (kinematics.md §1: the MMM model, scaled to the subject):

1. Height: the median upper arm plus forearm of the keypoints over the MMM model's (0.333 of the
   height), unless given.
2. Root: upright through the shoulders: x from the left to the right shoulder, z the vertical made
   orthogonal to it, the shoulder midpoint where the model has it. The torso joints stay at zero; a
   bending torso shows in the root's orientation.
3. Arms: a small IK on the MMM arm joints (mink + daqp, the robot solvers' machinery) in the root's
   frame: elbow and wrist positions, and the hand's orientation where the keypoints have knuckles
   (its position follows from the wrist's; knuckles sit elsewhere on a hand than the TCP), each arm
   shifted so that its shoulder is the model's (subjects' shoulders are not the model's width).
   Joint limits are the MMM ranges; warm-started from the previous frame, so the joints the
   keypoints leave free (forearm and wrist without knuckles) stay where they were.

The fitted motion keeps the keypoints as markers named ``left_elbow`` etc., so the fit error can be
measured and drawn at any later stage (:func:`fit_error`).
"""

from __future__ import annotations

import functools
from dataclasses import replace

import mujoco
import numpy as np

from hlik.human.keypoints import ARM_POINTS, HAND_POINTS, SIDES, Keypoints
from hlik.human.kinematics import forward_kinematics, human_model, human_spec, lowest_points, shoulder_frame
from hlik.human.motion import ARM_JOINTS, HumanMotion
from hlik.util.errors import MotionFormatError

# The markers a fitted motion carries: the keypoints it was fitted to.
KEYPOINT_MARKERS = tuple(f"{s}_{p}" for s in SIDES for p in (*ARM_POINTS, *HAND_POINTS))
ITERATIONS = 30  # IK steps at most per frame; frames converge in 2-5
STEP_TOL = 1e-6  # rad: a step below it ends the frame
# frames sampled, and m, below the frames it stands highest in, that the fitted body sinks where
# the subject bends over (OMOMO lifting a box: 0.5-0.7 m; standing takes within a few cm)
STOOP_SAMPLES = 100
STOOP_DEPTH = 0.15
# m: a fit whose elbows and wrists are this far off (median) is of mislabelled keypoints, refused
# (the LEGO and OMOMO takes fit within 1.4-4.5 cm; left and right shoulders swapped: 58 cm)
FIT_REFUSED = 0.15
HAND_ORIENTATION_COST = 0.1  # per rad against 1 per m: a hand frame 10° off weighs like 1.7 cm


@functools.lru_cache(maxsize=1)
def _mmm_ratios() -> tuple[float, np.ndarray, np.ndarray]:
    """Upper arm + forearm, shoulder midpoint (3,) in the root frame and shoulder positions (2, 3),
    of the 1 m MMM model at zero pose."""
    model = human_model(1.0)
    data = mujoco.MjData(model)
    data.qpos[:7] = (0, 0, 0, 1, 0, 0, 0)  # the root at the origin (qpos0 holds the model's standing height)
    mujoco.mj_kinematics(model, data)
    site = {
        n: data.site_xpos[model.site(n).id].copy() for n in (f"{s}_{p}" for s in SIDES for p in ARM_POINTS)
    }
    arm = np.linalg.norm(site["left_elbow"] - site["left_shoulder"]) + np.linalg.norm(
        site["left_wrist"] - site["left_elbow"]
    )
    shoulders = np.stack([site["left_shoulder"], site["right_shoulder"]])
    return float(arm), shoulders.mean(axis=0), shoulders


def estimate_height(keypoints: Keypoints) -> float:
    """Subject height in m from the median arm length (upper arm + forearm) of the keypoints."""
    arm = np.linalg.norm(keypoints.elbow - keypoints.shoulder, axis=-1) + np.linalg.norm(
        keypoints.wrist - keypoints.elbow, axis=-1
    )
    return float(np.median(arm)) / _mmm_ratios()[0]


def _arm_model(height: float) -> mujoco.MjModel:
    """The MMM model of ``height`` with its root fixed at the origin and only the arm joints."""
    spec = human_spec(height)
    keep = {j for side in SIDES for j in ARM_JOINTS[side]}
    for joint in list(spec.joints):
        if joint.name not in keep:
            spec.delete(joint)
    for body in spec.worldbody.bodies:  # the root body, standing in the file
        body.pos = np.zeros(3)
    return spec.compile()


def fit_mmm(keypoints: Keypoints, height: float | None = None) -> HumanMotion:
    """The MMM motion that best matches ``keypoints``.

    Args:
        keypoints: Arm keypoints (z up, metres).
        height: Subject height in m; estimated from the arm lengths if None.

    Returns:
        A motion with the 14 MMM arm joints, the root pose, ``height``, the keypoints as markers
        (``{side}_{shoulder,elbow,wrist,index,pinky}``) and a note with the fit error.

    Raises:
        MotionFormatError: shoulders that coincide in the horizontal plane (no heading); a fit
            whose elbows and wrists are further off than :data:`FIT_REFUSED` (median).
    """
    height = estimate_height(keypoints) if height is None else height
    _, mid0, shoulders0 = _mmm_ratios()
    mid0, shoulders0 = mid0 * height, shoulders0 * height
    root_rot, root_pos = _root_frames(keypoints, mid0)
    names, joints = _fit_arms(keypoints, height, root_rot, root_pos, shoulders0)
    motion = HumanMotion(
        name=keypoints.name,
        times=keypoints.times,
        joint_names=names,
        joints=joints,
        root_position=root_pos,
        root_rotation=root_rot,
        height=height,
        markers=_markers(keypoints),
        source=keypoints.source,
        notes=keypoints.notes,
    )
    error = fit_error(motion)
    assert error is not None  # a fitted motion carries its keypoints
    if np.median(error) > FIT_REFUSED:
        raise MotionFormatError(
            keypoints.source,
            f"motion: the keypoints do not fit a human's arms: elbows and wrists "
            f"{100 * np.median(error):.0f} cm off the fitted MMM model (median; a take's fit is within "
            f"{100 * FIT_REFUSED:.0f} cm); check the [keypoints] table (left and right swapped, a joint "
            "mislabelled)",
        )
    return replace(motion, notes=(*motion.notes, *_fit_notes(motion, keypoints, error, height, shoulders0)))


def _root_frames(keypoints: Keypoints, mid0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The root's rotation (T, 3, 3) and position (T, 3), upright through the shoulders, for a model
    whose shoulders' midpoint sits at ``mid0`` (3,) in the root frame.

    Raises:
        MotionFormatError: shoulders that coincide in the horizontal plane (no heading).
    """
    n = keypoints.n_frames
    root_rot, root_pos = np.empty((n, 3, 3)), np.empty((n, 3))
    for k in range(n):
        try:
            rot, mid = _upright_through(keypoints.shoulder[k, 0], keypoints.shoulder[k, 1])
        except ValueError:
            raise MotionFormatError(
                keypoints.source,
                f"frame {k} ({keypoints.times[k]:.2f} s): the shoulders coincide, no heading",
            ) from None
        root_rot[k], root_pos[k] = rot, mid - rot @ mid0
    return root_rot, root_pos


def _fit_arms(
    keypoints: Keypoints,
    height: float,
    root_rot: np.ndarray,
    root_pos: np.ndarray,
    shoulders0: np.ndarray,
) -> tuple[tuple[str, ...], np.ndarray]:
    """The arm model's joint names and angles (T, nq) whose elbows and wrists (and hands'
    orientations, where the keypoints have them) meet the keypoints', frame by frame with mink,
    each arm moved so that its shoulder is the model's (``shoulders0`` (2, 3), root frame)."""
    import mink  # the solvers' IK; not needed to measure a fit (fit_error)

    hands = keypoints.hand_frames()
    model = _arm_model(height)
    config = mink.Configuration(model)
    tasks = {
        (side, point): mink.FrameTask(f"{side}_{point}", "site", position_cost=1.0, orientation_cost=0.0)
        for side in SIDES
        for point in ("elbow", "wrist")
    }
    if hands is not None:
        tasks |= {
            (side, "tcp"): mink.FrameTask(
                f"{side}_tcp", "site", position_cost=0.0, orientation_cost=HAND_ORIENTATION_COST
            )
            for side in SIDES
        }
    limits = [mink.ConfigurationLimit(model)]
    names = tuple(model.joint(i).name for i in range(model.njnt))
    q = np.zeros(model.nq)
    # the arms start bent a little: a straight elbow is a singular start for the swivel
    for side in SIDES:
        q[names.index(ARM_JOINTS[side][3])] = 0.5
    joints = np.empty((keypoints.n_frames, model.nq))
    eye = np.eye(3)
    for k in range(keypoints.n_frames):
        rot, origin = root_rot[k], root_pos[k]
        for i, side in enumerate(SIDES):
            # the arm in the root frame, its shoulder moved onto the model's
            shift = rot.T @ (keypoints.shoulder[k, i] - origin) - shoulders0[i]
            for point, world in (("elbow", keypoints.elbow), ("wrist", keypoints.wrist)):
                local = rot.T @ (world[k, i] - origin) - shift
                tasks[(side, point)].set_target(
                    mink.SE3.from_rotation_and_translation(mink.SO3.from_matrix(eye), local)
                )
            if hands is not None:
                local = rot.T @ (hands[0][k, i] - origin) - shift
                frame = mink.SO3.from_matrix(rot.T @ hands[1][k, i])
                tasks[(side, "tcp")].set_target(mink.SE3.from_rotation_and_translation(frame, local))
        config.update(q)
        for _ in range(ITERATIONS * (5 if k == 0 else 1)):
            v = mink.solve_ik(config, list(tasks.values()), 1.0, "daqp", 1e-4, limits=limits)
            config.integrate_inplace(v, 1.0)
            if np.linalg.norm(v) < STEP_TOL:
                break
        q = config.q.copy()
        joints[k] = q
    return names, joints


def _markers(keypoints: Keypoints) -> dict[str, np.ndarray]:
    """The keypoints as markers, ``{side}_{shoulder,elbow,wrist,index,pinky}`` (T, 3) each."""
    markers = {f"{side}_shoulder": keypoints.shoulder[:, i] for i, side in enumerate(SIDES)}
    markers |= {f"{side}_elbow": keypoints.elbow[:, i] for i, side in enumerate(SIDES)}
    markers |= {f"{side}_wrist": keypoints.wrist[:, i] for i, side in enumerate(SIDES)}
    for point, values in (("index", keypoints.index), ("pinky", keypoints.pinky)):
        if values is not None:
            markers |= {f"{side}_{point}": values[:, i] for i, side in enumerate(SIDES)}
    return markers


def _fit_notes(
    motion: HumanMotion, keypoints: Keypoints, error: np.ndarray, height: float, shoulders0: np.ndarray
) -> list[str]:
    """What the fit says of itself: the elbows' and wrists' ``error`` (T,) (:func:`fit_error`), the
    shoulders' width against the model's, a subject that bends over, a hand without knuckles (a
    subject that walks is :meth:`HumanMotion.walking`'s, on the span retargeted)."""
    where = f"{keypoints.source}: " if keypoints.source else ""
    worst = int(np.argmax(error))
    wider = np.median(
        np.linalg.norm(keypoints.shoulder[:, 1] - keypoints.shoulder[:, 0], axis=-1)
    ) - np.linalg.norm(shoulders0[1] - shoulders0[0])
    note = (
        f"{where}MMM fitted to the keypoints (height {height:.2f} m): elbows and wrists off by "
        f"{100 * np.median(error):.1f} cm median, {100 * error[worst]:.1f} cm at most "
        f"({keypoints.times[worst]:.2f} s of the take); the subject's shoulders are "
        + (
            "as wide as the model's"
            if abs(wider) < 0.0005
            else f"{100 * abs(wider):.1f} cm {'wider' if wider > 0 else 'narrower'} than the model's"
        )
    )
    notes: list[str] = []
    rows, lowest = lowest_points(motion, STOOP_SAMPLES)
    sunk = lowest < np.percentile(lowest, 90) - STOOP_DEPTH
    if sunk.any():
        notes.append(
            f"{where}the subject bends over (its keypoints' shoulders drop) in {100 * sunk.mean():.0f} % of "
            "the take: the fit keeps the trunk upright under the shoulders, so the drawn body sinks up to "
            f"{-np.min(lowest):.2f} m into the floor at {keypoints.times[rows[np.argmin(lowest)]]:.2f} s and "
            "its trunk lean reads 0; the hands, which the robot follows, stay on the wrists"
        )
    if keypoints.hand_frames() is None:
        note += (
            "; no knuckles (index, pinky): the hands' orientation is not measured, it is the "
            "forearm's with the wrist straight and the forearm's twist as the fit left it, so the "
            "robot's hands follow that guess and fORI measures against it"
        )
    return [note, *notes]


def _upright_through(left: np.ndarray, right: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(3, 3) rotation with x along the shoulders (tilt kept), z as vertical as that allows; (3,) midpoint."""
    x = right - left
    z = np.array([0.0, 0.0, 1.0]) - x * (x[2] / max(float(x @ x), 1e-24))
    if np.linalg.norm(x) < 1e-9 or np.linalg.norm(z) < 1e-9:
        raise ValueError("degenerate shoulders")
    shoulder_frame(left, right)  # raises if the heading is undefined
    x, z = x / np.linalg.norm(x), z / np.linalg.norm(z)
    return np.column_stack([x, np.cross(z, x), z]), (left + right) / 2


def keypoint_markers(motion: HumanMotion) -> dict[str, np.ndarray]:
    """The markers of ``motion`` that are keypoints it was fitted to (none for an MMM recording)."""
    return {k: v for k, v in motion.markers.items() if k in KEYPOINT_MARKERS}


def fit_error(motion: HumanMotion) -> np.ndarray | None:
    """(T,) largest distance in m between the fitted elbows and wrists and the keypoint markers they
    were fitted to, each arm measured from its shoulder (the arm's shape, not the shoulders' width);
    None if the motion carries no such markers (an MMM recording)."""
    names = [f"{s}_{p}" for s in SIDES for p in ARM_POINTS]
    if not all(n in motion.markers for n in names):
        return None
    fk = forward_kinematics(motion)
    fitted = np.concatenate([fk.elbow - fk.shoulder, fk.wrist - fk.shoulder], axis=1)  # (T, 4, 3)
    markers = {n: motion.markers[n] for n in names}
    shoulder = np.stack([markers["left_shoulder"], markers["right_shoulder"]], axis=1)
    source = np.concatenate(
        [
            np.stack([markers["left_elbow"], markers["right_elbow"]], axis=1) - shoulder,
            np.stack([markers["left_wrist"], markers["right_wrist"]], axis=1) - shoulder,
        ],
        axis=1,
    )
    return np.max(np.linalg.norm(fitted - source, axis=-1), axis=1)
