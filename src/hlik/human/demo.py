"""The bundled demonstration motion: a bimanual pour followed by a wipe, authored here.

Key poses are written in MMM joint space (rad) and joined with minimum-jerk timing
(Flash & Hogan: s(τ) = 10τ³ - 15τ⁴ + 6τ⁵), so the motion is smooth and human-like without any
recorded data. ``python -m hlik.human.demo`` rewrites ``hlik/data/demo_pour_wipe.xml`` and its
arm skeleton as BVH, ``hlik/data/demo_pour_wipe.bvh`` (30 Hz).
"""

from __future__ import annotations

import numpy as np

from hlik.human.bvh import write_bvh
from hlik.human.mmm_format import read_mmm, write_mmm
from hlik.human.motion import HumanMotion
from hlik.util.paths import demo_bvh_path, demo_motion_path

HEIGHT = 1.75  # m
RATE = 25.0  # Hz; commands resample to their own rate
JOINTS = (
    "BPx_joint", "BPy_joint", "BPz_joint", "BTx_joint", "BTy_joint", "BTz_joint",
    "BLNx_joint", "BLNy_joint", "BLNz_joint", "BUNx_joint", "BUNy_joint", "BUNz_joint",
    "LSx_joint", "LSy_joint", "LSz_joint", "LEx_joint", "LEz_joint", "LWx_joint", "LWy_joint",
    "RSx_joint", "RSy_joint", "RSz_joint", "REx_joint", "REz_joint", "RWx_joint", "RWy_joint",
)  # fmt: skip

_REST = {"LSx": 0.05, "LSy": 0.12, "LEx": 0.25, "RSx": 0.05, "RSy": -0.12, "REx": 0.25}
_HOLD_CUP = {"LSx": 0.55, "LSy": 0.25, "LSz": 0.45, "LEx": 1.45, "LEz": -0.2, "LWy": 0.1}
_GRASP_BOTTLE = {"RSx": 0.75, "RSy": -0.3, "RSz": -0.1, "REx": 1.25, "REz": 0.1, "RWx": -0.1}
_POUR = {
    "RSx": 0.95,
    "RSy": -0.45,
    "RSz": -0.5,
    "REx": 1.45,
    "REz": 1.15,
    "RWx": -0.2,
    "BTx": 0.08,
    "BLNx": 0.15,
}
_PLATE = {"LSx": 0.45, "LSy": 0.3, "LSz": 0.35, "LEx": 1.25, "LWy": -0.25, "BTx": 0.12}


def _wipe(phase: float) -> dict[str, float]:
    """Right hand on a circle on the table (phase in rad)."""
    return {
        "RSx": 0.62 + 0.12 * np.sin(phase),
        "RSy": -0.3 + 0.12 * np.cos(phase),
        "RSz": -0.25 + 0.15 * np.cos(phase),
        "REx": 1.05 - 0.15 * np.sin(phase),
        "REz": -0.3,
        "RWy": -0.2,
        "BTx": 0.12,
        "BTz": 0.05 * np.cos(phase),
    }


def key_poses() -> list[tuple[float, dict[str, float]]]:
    """(duration of the move into the pose in s, pose) pairs; unspecified joints are 0."""
    keys = [
        (0.0, _REST),
        (1.2, _REST | _HOLD_CUP),
        (1.0, _REST | _HOLD_CUP | _GRASP_BOTTLE),
        (1.3, _HOLD_CUP | _POUR),
        (0.8, _HOLD_CUP | _POUR | {"REz": 0.9}),
        (1.0, _HOLD_CUP | _GRASP_BOTTLE),
        (1.2, _REST | _PLATE | {"RSx": 0.3, "REx": 0.8}),
    ]
    keys += [(0.55, _REST | _PLATE | _wipe(p)) for p in np.linspace(0, 4 * np.pi, 9)]
    keys += [(1.2, _REST)]
    return keys


def demo_motion() -> HumanMotion:
    """The demo as a :class:`HumanMotion` (no markers, no objects)."""
    keys = key_poses()
    poses = np.array([[p.get(j.removesuffix("_joint"), 0.0) for j in JOINTS] for _, p in keys])
    starts = np.cumsum([d for d, _ in keys])
    times = np.arange(0.0, starts[-1] + 1e-9, 1.0 / RATE)
    seg = np.clip(np.searchsorted(starts, times, side="right") - 1, 0, len(keys) - 2)
    tau = (times - starts[seg]) / np.diff(starts)[seg]
    s = 10 * tau**3 - 15 * tau**4 + 6 * tau**5
    joints = poses[seg] + s[:, None] * (poses[seg + 1] - poses[seg])
    n = len(times)
    return HumanMotion(
        name="demo_pour_wipe",
        times=times,
        joint_names=JOINTS,
        joints=joints,
        root_position=np.tile([0.0, 0.0, 0.530 * HEIGHT], (n, 1)),
        root_rotation=np.tile(np.eye(3), (n, 1, 1)),
        height=HEIGHT,
        mass=70.0,
    )


if __name__ == "__main__":
    path = demo_motion_path()
    path.parent.mkdir(parents=True, exist_ok=True)
    write_mmm(demo_motion(), path)
    print(f"wrote {path}")
    print(f"wrote {write_bvh(read_mmm(path), demo_bvh_path())}")  # from the file, as a user reads it
