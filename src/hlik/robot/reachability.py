"""Oriented reachability maps of a robot's hands (Vahrenkamp, Asfour, Dillmann, ICRA 2013).

A map voxelises the 6D TCP pose in the robot base frame: position in cubic cells, orientation in
equal-volume bins of the ZYZ Euler angles (azimuth and polar cosine of the approach axis z, roll
about it). Random configurations of the arms (and the joints solved with them, ARMAR-III's hip) are
drawn within the joint limits; self-colliding ones are dropped, and so are hands behind the frontal
plane through the shoulders (at home): the robot can reach there, but a person does not work behind
their back, and a placement that needs it is the fault this map is for. Each entry counts the samples whose
TCP lands within one cell and one orientation bin of it (formulas.md §7: Simox fills neighbouring
cells). The counting window makes the map dense enough at a few hundred thousand samples to call
no pose of a tracked motion unreachable, and its count grows towards the middle of the workspace,
away from joint limits and the body, which is where the placement search pushes the hands. Maps are
sampled once per model (seconds) and cached on disk.

Cache entries (these maps, and :mod:`hlik.criteria.learned`'s pieces) are trusted only as far as
they prove themselves: each carries its key (format, robot, a hash of the model, what it was made
from) and a checksum of its arrays. An entry that is unreadable, edited, or written for another key
is made again, with a one-line note on the result (``notes``) that the CLI prints.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from dataclasses import dataclass, replace
from functools import cached_property

import mujoco
import numpy as np
from scipy.ndimage import uniform_filter

from hlik.robot.model import SIDES, SITES, Robot
from hlik.util.cache import UNREADABLE, entry_path, one_line, read_entry, write_entry
from hlik.util.spatial import site_poses

CACHE_VERSION = "reach/3"  # 2: hands in front of the shoulders only; 3: entries carry key and checksum
CELL = 0.08  # m, position cell
AZIMUTH_BINS, POLAR_BINS, ROLL_BINS = 6, 4, 6  # 60 deg x (cos steps of 0.5) x 60 deg
N_SAMPLES = 400_000
UNLIMITED_RANGE = np.pi  # an unlimited joint is sampled in [-pi, pi]
SEED = 0


@dataclass(frozen=True, eq=False)
class ReachabilityMap:
    """Reachability of both TCPs over the 6D pose grid, robot base frame.

    Attributes:
        robot: Robot name.
        origin: (3,) corner of the first position cell, base frame, m.
        cell: Edge of a position cell, m.
        counts: (2, nx, ny, nz, n_orientation) uint16 samples within one cell and bin of each
            entry, arms in :data:`SIDES` order.
        n_samples: Configurations sampled (before removing self-collisions).
        notes: One line per thing worth telling about where the map came from (a cache entry that
            was unreadable or did not match and was sampled again, or could not be written).
    """

    robot: str
    origin: np.ndarray
    cell: float
    counts: np.ndarray
    n_samples: int
    notes: tuple[str, ...] = ()

    def lookup(self, side: int, pos: np.ndarray, rot: np.ndarray) -> np.ndarray:
        """Map entries of TCP poses of arm ``side`` (0 = left): positions (..., 3) and rotations
        (..., 3, 3) in the base frame (broadcast together); 0 outside the grid."""
        flat, shape = self._padded
        cells = np.floor((pos - self.origin) / self.cell).astype(np.intp) + 1
        np.clip(cells, 0, np.array(shape[:3]) - 1, out=cells)  # outside lands in the zero border
        linear = ((cells[..., 0] * shape[1] + cells[..., 1]) * shape[2] + cells[..., 2]) * shape[3]
        return flat[side][linear + orientation_bin(rot)]

    @cached_property
    def _padded(self) -> tuple[np.ndarray, tuple[int, ...]]:
        padded = np.pad(self.counts, ((0, 0), (1, 1), (1, 1), (1, 1), (0, 0)))
        return padded.reshape(2, -1), padded.shape[1:]


def orientation_bin(rot: np.ndarray) -> np.ndarray:
    """Bin index (...) of rotations (..., 3, 3): ZYZ Euler R = Rz(a) Ry(b) Rz(c), binned in a,
    cos b and c, which is uniform in the rotation group's volume."""
    z = rot[..., :, 2]
    azimuth = np.arctan2(z[..., 1], z[..., 0])
    roll = np.arctan2(rot[..., 2, 1], -rot[..., 2, 0])
    a = _bin((azimuth + np.pi) / (2 * np.pi), AZIMUTH_BINS)
    b = _bin((1.0 - np.clip(z[..., 2], -1.0, 1.0)) / 2.0, POLAR_BINS)
    c = _bin((roll + np.pi) / (2 * np.pi), ROLL_BINS)
    return (a * POLAR_BINS + b) * ROLL_BINS + c


def _bin(u: np.ndarray, n: int) -> np.ndarray:
    return np.minimum((u * n).astype(int), n - 1)


def reachability_map(
    robot: Robot,
    cache: bool = True,
    n_samples: int = N_SAMPLES,
    progress: Callable[[int, int], None] | None = None,
) -> ReachabilityMap:
    """The robot's reachability map, from the cache (keyed by model, description and sampling) or
    sampled now (a few seconds; seeded, so the same model gives the same map). A cache entry that is
    unreadable or does not match is sampled again; ``notes`` says so. ``progress(k, n_samples)``
    reports the sampling (see :func:`sample_map`)."""
    key = {
        "format": CACHE_VERSION,
        "robot": robot.name,
        "model": model_key(robot),
        "sampling": f"{n_samples} samples, seed {SEED}, cell {CELL} m",
    }
    path = entry_path(f"reach-{robot.name}", key)
    notes = []
    if cache:
        arrays, problem = read_entry(path, key)
        if arrays is not None:
            try:
                return ReachabilityMap(
                    str(arrays["robot"]), arrays["origin"], float(arrays["cell"]), arrays["counts"],
                    int(arrays["n_samples"]),
                )  # fmt: skip
            except UNREADABLE as e:  # whole and of this key, yet not a map: a bug, not a user's file
                problem = f"does not hold a reachability map ({one_line(e)})"
        if problem is not None:
            notes.append(f"{path}: cache entry {problem}; sampled the map again")
    reach = sample_map(robot, n_samples, progress=progress)
    if cache:
        arrays = {
            "robot": np.array(reach.robot), "origin": reach.origin, "cell": np.array(reach.cell),
            "counts": reach.counts, "n_samples": np.array(reach.n_samples),
        }  # fmt: skip
        failed = write_entry(path, arrays, key, compressed=True)
        notes += [failed] if failed else []
    return replace(reach, notes=tuple(notes))


def sample_map(
    robot: Robot, n_samples: int, seed: int = SEED, progress: Callable[[int, int], None] | None = None
) -> ReachabilityMap:
    """Sample ``n_samples`` configurations uniformly within the limits of the arm and extra joints
    (the rest at home), drop self-colliding ones, and count both TCPs into the 6D grid.
    ``progress(k, n_samples)`` is called every 1000 samples and at the end."""
    model = robot.model
    data = mujoco.MjData(model)
    moving = np.unique(np.concatenate([robot.index(robot.extra_joints + robot.arm_joints[s]) for s in SIDES]))
    lo = np.where(np.isfinite(robot.lower), robot.lower, -UNLIMITED_RANGE)[moving]
    hi = np.where(np.isfinite(robot.upper), robot.upper, UNLIMITED_RANGE)[moving]
    q = np.tile(robot.home, (n_samples, 1))
    q[:, moving] = np.random.default_rng(seed).uniform(lo, hi, (n_samples, len(moving)))
    tcp = robot.site_ids[:, SITES.index("tcp")]
    pos = np.empty((n_samples, 2, 3))
    rot = np.empty((n_samples, 2, 9))
    free = np.empty(n_samples, dtype=bool)
    for k in range(n_samples):
        data.qpos[:] = q[k]
        mujoco.mj_kinematics(model, data)
        mujoco.mj_collision(model, data)
        free[k] = data.ncon == 0
        pos[k] = data.site_xpos[tcp]
        rot[k] = data.site_xmat[tcp]
        if progress is not None and ((k + 1) % 1000 == 0 or k + 1 == n_samples):
            progress(k + 1, n_samples)
    pos, tcp_rot = pos[free], rot[free].reshape(-1, 2, 3, 3)
    shoulder_y = site_poses(model, robot.home[None], robot.site_ids[:, SITES.index("shoulder")])[0][0, :, 1]
    front = pos[:, :, 1] > shoulder_y  # (N, 2); the robot faces +y
    origin = np.floor(pos.reshape(-1, 3).min(axis=0) / CELL) * CELL - CELL
    shape = (np.ceil((pos.reshape(-1, 3).max(axis=0) - origin) / CELL).astype(int) + 2).tolist()
    n_ori = AZIMUTH_BINS * POLAR_BINS * ROLL_BINS
    hits = np.zeros((2, *shape, n_ori), dtype=np.float32)
    for s in range(2):
        cells = np.floor((pos[front[:, s], s] - origin) / CELL).astype(int)
        bins = orientation_bin(tcp_rot[front[:, s], s])
        np.add.at(hits[s], (cells[:, 0], cells[:, 1], cells[:, 2], bins), 1.0)
    # Count over the neighbouring cells and bins: azimuth and roll wrap around, the polar cosine not.
    grid = hits.reshape(2, *shape, AZIMUTH_BINS, POLAR_BINS, ROLL_BINS)
    modes = ["constant"] * 4 + ["wrap", "nearest", "wrap"]
    window = np.rint(uniform_filter(grid, size=(1, 3, 3, 3, 3, 3, 3), mode=modes) * 3**6)
    counts = np.minimum(window.reshape(hits.shape), np.iinfo(np.uint16).max).astype(np.uint16)
    return ReachabilityMap(robot.name, origin, CELL, counts, n_samples)


# --- cache entries -----------------------------------------------------------------------------


def model_key(robot: Robot) -> str:
    """Hex digest of what a robot's cached pieces depend on: its compiled MuJoCo model (included
    files and meshes too) and its description (joints, limits, home, mapping, manipulability chain)."""
    mjb = np.empty(mujoco.mj_sizeModel(robot.model), dtype=np.uint8)
    mujoco.mj_saveModel(robot.model, None, mjb)
    digest = hashlib.sha256(mjb.tobytes())
    described = (
        robot.joint_names, robot.arm_joints, robot.extra_joints, robot.lower.tolist(),
        robot.upper.tolist(), robot.home.tolist(), robot.mapping, robot.manipulability_site,
        robot.manipulability_joints,
    )  # fmt: skip
    digest.update(repr(described).encode())
    return digest.hexdigest()
