"""Human forward kinematics on the MMM reference model scaled to the subject.

The model file is normalised to a 1 m tall subject; :func:`human_model` scales every length with
``mujoco.MjSpec`` so one file serves every subject height.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import mujoco
import numpy as np
from scipy.spatial.transform import Rotation

from hlik.human.motion import HumanMotion
from hlik.util.errors import SettingsError
from hlik.util.paths import robots_dir
from hlik.util.spatial import site_poses

SIDES = ("left", "right")


@dataclass(frozen=True, eq=False)
class HumanKinematics:
    """Arm joint centres and TCP poses over time; arm index 0 = left, 1 = right; metres, world.

    Attributes:
        shoulder, elbow, wrist, tcp_pos: (T, 2, 3) positions.
        tcp_rot: (T, 2, 3, 3) TCP orientations (z = approach, x = palm normal).
    """

    shoulder: np.ndarray
    elbow: np.ndarray
    wrist: np.ndarray
    tcp_pos: np.ndarray
    tcp_rot: np.ndarray


@functools.lru_cache(maxsize=16)
def human_model(height: float) -> mujoco.MjModel:
    """The MMM model scaled to a subject of ``height`` metres, compiled once per height.

    The model is shared: read it, make an ``MjData`` of it, never modify it.
    """
    return human_spec(height).compile()


def human_spec(height: float) -> mujoco.MjSpec:
    """A fresh ``MjSpec`` of the MMM model scaled to a subject of ``height`` metres."""
    spec = mujoco.MjSpec.from_file(str(robots_dir() / "mjcf" / "mmm.xml"))
    for body in spec.bodies:
        body.pos = np.asarray(body.pos) * height
    for site in spec.sites:
        site.pos = np.asarray(site.pos) * height
    for geom in spec.geoms:
        geom.pos = np.asarray(geom.pos) * height
        geom.size = np.asarray(geom.size) * height
        fromto = np.asarray(geom.fromto)
        if np.all(np.isfinite(fromto)):
            geom.fromto = fromto * height
    return spec


def qpos_trajectory(model: mujoco.MjModel, motion: HumanMotion) -> np.ndarray:
    """(T, nq) MuJoCo configurations of ``model`` for every frame of ``motion``.

    Joints are matched by name; recorded joints the model lacks (fingers, clavicles) are ignored.
    """
    qpos = np.zeros((motion.n_frames, model.nq))
    qpos[:, :3] = motion.root_position
    qpos[:, 3:7] = np.roll(Rotation.from_matrix(motion.root_rotation).as_quat(), 1, axis=-1)  # wxyz
    for i, name in enumerate(motion.joint_names):
        jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
        if jid >= 0:
            qpos[:, model.jnt_qposadr[jid]] = motion.joints[:, i]
    return qpos


def forward_kinematics(motion: HumanMotion) -> HumanKinematics:
    """Joint centres and TCP poses of both arms for every frame of ``motion``."""
    model = human_model(motion.height)
    names = ("shoulder", "elbow", "wrist", "tcp")
    ids = np.array([[model.site(f"{s}_{n}").id for s in SIDES] for n in names])
    pos, rot = site_poses(model, qpos_trajectory(model, motion), ids)
    return HumanKinematics(pos[:, 0], pos[:, 1], pos[:, 2], pos[:, 3], rot[:, 3])


def lowest_points(motion: HumanMotion, samples: int = 24) -> tuple[np.ndarray, np.ndarray]:
    """(k,) the frames sampled, ``samples`` spread over the take, and (k,) the lowest height, m,
    of the MMM body's geometry at each (its axis-aligned boxes: a few mm low at worst)."""
    model = human_model(motion.height)
    data = mujoco.MjData(model)
    rows = np.arange(0, len(motion.times), max(1, -(-len(motion.times) // samples)))
    lowest = np.empty(len(rows))
    for k, qpos in enumerate(qpos_trajectory(model, motion.frames(rows))):
        data.qpos[:] = qpos
        mujoco.mj_kinematics(model, data)
        rot = data.geom_xmat.reshape(-1, 3, 3)
        centre = data.geom_xpos[:, 2] + np.einsum("gj,gj->g", rot[:, 2], model.geom_aabb[:, :3])
        lowest[k] = np.min(centre - np.einsum("gj,gj->g", np.abs(rot[:, 2]), model.geom_aabb[:, 3:]))
    return rows, lowest


def shoulder_axes(left: np.ndarray, right: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The horizontal unit vectors (..., 3) toward the right shoulder and forward (z x right) of a
    body z up, from its shoulder positions (..., 3) each; the frontal plane's in-plane and normal
    directions (NaN where the shoulders coincide in the horizontal plane)."""
    across = np.asarray(right, dtype=float) - np.asarray(left, dtype=float)
    across = across * np.array([1.0, 1.0, 0.0])
    with np.errstate(invalid="ignore", divide="ignore"):
        across = across / np.linalg.norm(across, axis=-1, keepdims=True)
    front = np.stack([-across[..., 1], across[..., 0], np.zeros(across.shape[:-1])], axis=-1)
    return across, front


def arm_length(shoulder: np.ndarray, elbow: np.ndarray, wrist: np.ndarray) -> np.ndarray:
    """(...) each arm's length, shoulder to elbow plus elbow to wrist, from joint centres (..., 3)."""
    return np.linalg.norm(elbow - shoulder, axis=-1) + np.linalg.norm(wrist - elbow, axis=-1)


def shoulder_frame(left: np.ndarray, right: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Upright frame at the shoulder midpoint: x towards the right shoulder, y forward, z up.

    Args:
        left, right: (3,) shoulder positions.

    Returns:
        (3, 3) rotation (columns x, y, z) and (3,) origin.
    """
    x = np.array([right[0] - left[0], right[1] - left[1], 0.0])
    norm = np.linalg.norm(x)
    if norm < 1e-9:
        raise SettingsError("shoulders coincide in the horizontal plane; heading undefined")
    x /= norm
    z = np.array([0.0, 0.0, 1.0])
    return np.column_stack([x, np.cross(z, x), z]), (left + right) / 2.0
