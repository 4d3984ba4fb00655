"""Writing a motion's arm skeleton as BVH: the joint centres of the MMM model (forward kinematics) in
the layout most exporters use (Y up, centimetres, ``Hips``/``Spine``/``LeftArm``/``LeftForeArm``/
``LeftHand`` names), so that hlik's BVH reader (:func:`hlik.human.keypoints.read_bvh`) and other
tools read it.

Every joint carries position channels and no rotation: a joint's position is its parent's plus its
own channels, which holds the joint centres exactly (a BVH of rotations would need a fitted
skeleton of constant bone lengths). ``python -m hlik.human.demo`` writes the bundled demo's
(``hlik/data/demo_pour_wipe.bvh``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from hlik.human.kinematics import forward_kinematics
from hlik.human.motion import HumanMotion
from hlik.util.atomic import atomic_path

# z-up metres (hlik) -> Y-up centimetres (BVH): x stays, y_bvh = z, z_bvh = -y (a proper rotation)
_TO_BVH = 100.0 * np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
_POSITION = "CHANNELS 3 Xposition Yposition Zposition"


def write_bvh(motion: HumanMotion, path: str | Path, rate: float = 30.0) -> Path:
    """Write ``motion``'s pelvis, shoulders' midpoint, shoulders, elbows, wrists and TCPs as a BVH
    sampled at ``rate`` Hz, atomically; returns the path.

    Joints (parent first): ``Hips`` (the MMM root) -> ``Spine`` (the shoulders' midpoint) ->
    ``{Left,Right}Arm`` (shoulder) -> ``ForeArm`` (elbow) -> ``Hand`` (wrist) -> ``HandEnd`` (TCP).
    """
    path = Path(path)
    if rate > 0 and motion.n_frames > 1:
        motion = motion.resample(rate)
    kin = forward_kinematics(motion)
    points = {
        "Hips": motion.root_position,
        "Spine": kin.shoulder.mean(axis=1),
        **{f"{side}Arm": kin.shoulder[:, i] for i, side in enumerate(("Left", "Right"))},
        **{f"{side}ForeArm": kin.elbow[:, i] for i, side in enumerate(("Left", "Right"))},
        **{f"{side}Hand": kin.wrist[:, i] for i, side in enumerate(("Left", "Right"))},
        **{f"{side}HandEnd": kin.tcp_pos[:, i] for i, side in enumerate(("Left", "Right"))},
    }
    parents = {"Spine": "Hips"}
    for side in ("Left", "Right"):
        parents |= {f"{side}Arm": "Spine", f"{side}ForeArm": f"{side}Arm", f"{side}Hand": f"{side}ForeArm"}
        parents[f"{side}HandEnd"] = f"{side}Hand"
    local = {n: (p - (points[parents[n]] if n in parents else 0.0)) @ _TO_BVH.T for n, p in points.items()}
    order = ["Hips", "Spine"] + [
        f"{s}{j}" for s in ("Left", "Right") for j in ("Arm", "ForeArm", "Hand", "HandEnd")
    ]
    lines = ["HIERARCHY", *_joint("Hips", local, parents, 0)]
    period = float(np.median(np.diff(motion.times))) if motion.n_frames > 1 else 1.0 / 30.0
    lines += ["MOTION", f"Frames: {motion.n_frames}", f"Frame Time: {period:.7f}"]
    values = np.concatenate([local[n] for n in order], axis=1)  # (T, 3 per joint)
    lines += [_numbers(row) for row in values]
    with atomic_path(path) as tmp:
        tmp.write_text("\n".join(lines) + "\n", encoding="ascii")
    return path


def _joint(name: str, local: dict[str, np.ndarray], parents: dict[str, str], depth: int) -> list[str]:
    """The HIERARCHY lines of ``name`` and its children; the first frame's offsets."""
    pad = "  " * depth
    kind = "ROOT" if depth == 0 else "JOINT"
    offset = _numbers(local[name][0])
    lines = [f"{pad}{kind} {name}", f"{pad}{{", f"{pad}  OFFSET {offset}", f"{pad}  {_POSITION}"]
    for child in (c for c, p in parents.items() if p == name):
        lines += _joint(child, local, parents, depth + 1)
    if not any(p == name for p in parents.values()):
        lines += [f"{pad}  End Site", f"{pad}  {{", f"{pad}    OFFSET 0.0 0.0 0.0", f"{pad}  }}"]
    return lines + [f"{pad}}}"]


def _numbers(values: np.ndarray) -> str:
    """Values to 0.1 mm, a zero unsigned: the sign of a 1e-17 remainder of the kinematics is no part
    of the file (it differed between MuJoCo releases)."""
    return " ".join(f"{v:.4f}" for v in np.round(values, 4) + 0.0)
