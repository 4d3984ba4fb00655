"""Keypoint streams as pose estimators write them, made fit to be fitted: dropouts, left/right swaps
and limb outliers.

Pose estimators write an undetected keypoint as ``0 0 0`` or ``-1 -1 -1`` (OpenPose:
CMU-Perceptual-Computing-Lab/openpose #2018, #131) and confuse the left and right limbs for a few
frames (huchenlei/sd-webui-openpose-editor #51; LeCAR-Lab/human2humanoid #71). Fitted as they are,
a dropout is a jump to the camera origin and a swap turns the fitted subject round; a warm-started
fit then stays on the wrong branch. Here a dropout becomes a gap (NaN, filled or refused by the
reader's gap rule), a swap is swapped back, and a limb whose length leaves its median by more than
:data:`LIMB_TOLERANCE` becomes a gap; each with a one-line note naming the keypoint and time span.

Every function takes ``points``: keypoint name (``left_elbow``, ...) -> (T, 3) positions, and
changes nothing in place.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from hlik.human.motion import stretches

SENTINELS = (0.0, -1.0)  # what estimators write for a keypoint they did not detect
# a limb (shoulder-elbow, elbow-wrist) longer or shorter than its take's median by this share is a
# misdetection in that frame: real limbs keep their length; estimation noise is a few per cent
LIMB_TOLERANCE = 0.35
# the shoulder line turned this far from its median direction (seen from above) in a frame: the
# labels are swapped there (a person does not turn round within a few frames of a take)
SWAP_ANGLE = np.radians(120.0)
LIMBS = (("shoulder", "elbow"), ("elbow", "wrist"))
SIDES = ("left", "right")


def spans(mask: np.ndarray, times: np.ndarray, shown: int = 3) -> str:
    """The runs of True in ``mask`` (T,) as ``"1.20-1.70 s, 3.00 s"`` (at most ``shown``, then
    ``"and N more"``)."""
    runs = stretches(mask)
    text = [
        f"{times[a]:.2f} s" if b - a == 1 else f"{times[a]:.2f}-{times[b - 1]:.2f} s" for a, b in runs[:shown]
    ]
    more = f" and {len(runs) - shown} more" if len(runs) > shown else ""
    return ", ".join(text) + more


def dropouts(points: Mapping[str, np.ndarray]) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """``points`` with every frame where a keypoint is exactly a sentinel (``0 0 0``, ``-1 -1 -1``)
    set to NaN, and name -> (T,) the frames so set (only keypoints with any)."""
    out, found = {}, {}
    for name, value in points.items():
        gone = np.zeros(len(value), dtype=bool)
        for s in SENTINELS:
            gone |= np.all(value == s, axis=1)
        out[name] = np.where(gone[:, None], np.nan, value)
        if gone.any():
            found[name] = gone
    return out, found


def swapped_frames(points: Mapping[str, np.ndarray]) -> np.ndarray:
    """(T,) True where the left and right labels are swapped as a whole: the shoulder line (right
    to left, seen from above, z up) points more than :data:`SWAP_ANGLE` away from its median."""
    line = (points["left_shoulder"] - points["right_shoulder"])[:, :2]
    angle = np.arctan2(line[:, 1], line[:, 0])
    median = np.arctan2(np.median(np.sin(angle)), np.median(np.cos(angle)))
    return np.abs(np.angle(np.exp(1j * (angle - median)))) > SWAP_ANGLE


def swap_sides(points: Mapping[str, np.ndarray], frames: np.ndarray, part: str | None = None) -> dict:
    """``points`` with the left and right keypoints (of ``part`` only, e.g. ``wrist``; None: all)
    exchanged in ``frames`` (T,) bool."""
    out = dict(points)
    for name in points:
        side, _, rest = name.partition("_")
        if side == "left" and (part is None or rest == part) and f"right_{rest}" in points:
            left, right = points[name], points[f"right_{rest}"]
            out[name] = np.where(frames[:, None], right, left)
            out[f"right_{rest}"] = np.where(frames[:, None], left, right)
    return out


def limb_misfit(points: Mapping[str, np.ndarray], parent: str, child: str, swap: bool = False) -> np.ndarray:
    """(T,) both arms' relative length errors summed, of the limb ``parent``-``child`` against
    each side's median; with ``swap`` the children exchanged between the sides."""
    total = np.zeros(len(points[f"left_{parent}"]))
    for side, other in zip(SIDES, SIDES[::-1]):
        length = np.linalg.norm(points[f"{side}_{child}"] - points[f"{side}_{parent}"], axis=1)
        median = np.median(length)
        child_at = points[f"{other if swap else side}_{child}"]
        total += np.abs(np.linalg.norm(child_at - points[f"{side}_{parent}"], axis=1) / median - 1.0)
    return total


def limb_outliers(points: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Arm name (``left``, ``right``) -> (T,) frames where one of its limbs is off its median length
    by more than :data:`LIMB_TOLERANCE` (only arms with any)."""
    found = {}
    for side in SIDES:
        bad = np.zeros(len(points[f"{side}_shoulder"]), dtype=bool)
        for parent, child in LIMBS:
            length = np.linalg.norm(points[f"{side}_{child}"] - points[f"{side}_{parent}"], axis=1)
            bad |= np.abs(length / np.median(length) - 1.0) > LIMB_TOLERANCE
        if bad.any():
            found[side] = bad
    return found


def repair_swaps(points: Mapping[str, np.ndarray], times: np.ndarray) -> tuple[dict, list[str]]:
    """``points`` (z up) with whole-body swaps (:func:`swapped_frames`) and swaps of single joints
    (an elbow or a wrist that fits the other arm's limb far better than its own) swapped back, and
    one note per repair naming the time spans."""
    notes = []
    whole = swapped_frames(points)
    if whole.any():
        points = swap_sides(points, whole)
        notes.append(f"left and right keypoints swapped at {spans(whole, times)}; swapped back")
    for parent, child in LIMBS:
        own, crossed = limb_misfit(points, parent, child), limb_misfit(points, parent, child, swap=True)
        frames = (own > 2 * LIMB_TOLERANCE) & (crossed < 0.5 * own)
        if frames.any():
            points = swap_sides(points, frames, child)
            notes.append(f"left and right {child}s swapped at {spans(frames, times)}; swapped back")
    return dict(points), notes


def hands_behind(points: Mapping[str, np.ndarray]) -> float:
    """Median distance (m) of the wrists in front of the shoulders' frontal plane, facing as the
    labels say (z up: forward = (left - right shoulder) x up). Clearly negative over a whole take
    (the hands behind the back while they work) means the sides are labelled mirrored."""
    across = points["left_shoulder"] - points["right_shoulder"]
    forward = np.cross(across, [0.0, 0.0, 1.0])
    forward /= np.maximum(np.linalg.norm(forward, axis=1, keepdims=True), 1e-9)
    mid = (points["left_shoulder"] + points["right_shoulder"]) / 2
    ahead = [np.einsum("ti,ti->t", points[f"{s}_wrist"] - mid, forward) for s in SIDES]
    return float(np.median(np.concatenate(ahead)))
