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
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import mujoco
import numpy as np
from scipy.ndimage import uniform_filter

from hlik.atomic import atomic_path
from hlik.fk import site_poses
from hlik.paths import cache_dir, robots_dir
from hlik.robot.model import SIDES, SITES, Robot

CACHE_VERSION = "reach/2"  # 2: hands in front of the shoulders only
CELL = 0.08  # m, position cell
AZIMUTH_BINS, POLAR_BINS, ROLL_BINS = 6, 4, 6  # 60 deg x (cos steps of 0.5) x 60 deg
N_SAMPLES = 400_000
UNLIMITED_RANGE = np.pi  # an unlimited joint is sampled in [-pi, pi]


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
    """

    robot: str
    origin: np.ndarray
    cell: float
    counts: np.ndarray
    n_samples: int

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


def reachability_map(robot: Robot, cache: bool = True, n_samples: int = N_SAMPLES) -> ReachabilityMap:
    """The robot's reachability map, from the cache (keyed by model, description and sampling) or
    sampled now (a few seconds; seeded, so the same model gives the same map)."""
    path = cache_dir() / f"reach-{robot.name}-{_key(robot, n_samples)}.npz"
    if cache and path.is_file():
        try:
            return _load(path)
        except (OSError, KeyError, ValueError):
            pass  # a broken cache entry is sampled again
    reach = sample_map(robot, n_samples)
    if cache:
        path.parent.mkdir(parents=True, exist_ok=True)
        with atomic_path(path) as tmp, open(tmp, "wb") as f:
            np.savez_compressed(
                f, robot=np.array(reach.robot), origin=reach.origin, cell=np.array(reach.cell),
                counts=reach.counts, n_samples=np.array(reach.n_samples),
            )  # fmt: skip
    return reach


def sample_map(robot: Robot, n_samples: int, seed: int = 0) -> ReachabilityMap:
    """Sample ``n_samples`` configurations uniformly within the limits of the arm and extra joints
    (the rest at home), drop self-colliding ones, and count both TCPs into the 6D grid."""
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


def _key(robot: Robot, n_samples: int) -> str:
    digest = hashlib.sha256(f"{CACHE_VERSION}:{n_samples}:{CELL}".encode())
    for path in (robots_dir() / f"{robot.name}.toml", robot.mjcf):
        digest.update(Path(path).read_bytes())
    return digest.hexdigest()[:16]


def _load(path: Path) -> ReachabilityMap:
    with np.load(path, allow_pickle=False) as z:
        return ReachabilityMap(
            str(z["robot"]), z["origin"], float(z["cell"]), z["counts"], int(z["n_samples"])
        )
