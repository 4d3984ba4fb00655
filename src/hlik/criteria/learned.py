"""Learned pieces of the criteria, per robot: synergies, the Psi_human regressor and lambda_R.

They are fitted on a corpus of human motions (a folder of MMM files chosen by the user; default
the bundled demo) and cached on disk, keyed by robot and corpus content, so a change of either
refits. The corpus is resampled to 100 Hz, the first and last second of each recording dropped,
and every motion also mirrored (paper Sec. III-B).

A cache entry carries its key (format, robot name, model hash, corpus hash) and a checksum of its
arrays (:func:`hlik.robot.reachability.read_entry`): one replaced by another robot's, edited,
truncated or unreadable is fitted again, and :attr:`Learned.notes` says so in one line.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from hlik.criteria.eea import SwivelPredictor
from hlik.criteria.manipulability import scale_factor
from hlik.criteria.synergy import Synergies, fit_synergies
from hlik.human.kinematics import forward_kinematics, shoulder_frame
from hlik.human.load import load_motion
from hlik.human.motion import HumanMotion
from hlik.robot.model import SIDES, Robot, joint_mapping
from hlik.robot.reachability import model_key
from hlik.util.cache import UNREADABLE, entry_path, read_entry, write_entry
from hlik.util.errors import HlikError, MotionFormatError
from hlik.util.paths import demo_motion_path, robots_dir

RATE = 100.0
TRIM = 1.0  # s dropped at each end of a recording
# 4: first-order synergies over the joints the mapping moves, Psi_human on x-z-y hand angles,
# root rotations resampled by C2 splines; 5: entries carry their key and a checksum; 6: angles and
# positions resampled by quintic splines
CACHE_VERSION = "learned/6"


@dataclass(frozen=True, eq=False)
class Learned:
    """What a robot's criteria learn from human data.

    Attributes:
        robot: Robot name.
        corpus: Names of the corpus files.
        synergies: Postural and first-order synergies of the robot-mapped corpus.
        swivel: The Psi_human regressor refitted on the corpus (formulas.md §1.2).
        swivel_rms: Its RMS error on the corpus, rad.
        scale: lambda_R, the manipulability scale of the robot against the normalised MMM model.
        notes: One line per thing worth telling about where these came from (a cache entry that
            was unreadable or did not match and was fitted again, or could not be written).
    """

    robot: str
    corpus: tuple[str, ...]
    synergies: Synergies
    swivel: SwivelPredictor
    swivel_rms: float
    scale: float
    notes: tuple[str, ...] = ()


def corpus_files(folder: str | Path | None = None) -> list[Path]:
    """The motion files of a corpus folder (``*.xml``), or the bundled demo."""
    if folder is None:
        return [demo_motion_path()]
    folder = Path(folder)
    if not folder.exists():
        raise HlikError(f"{folder}: no such folder or file for the corpus")
    files = sorted(folder.glob("*.xml")) if folder.is_dir() else [folder]
    if not files or not all(f.is_file() for f in files):
        raise HlikError(f"{folder}: no motion files (*.xml) found for the corpus")
    return files


def learn(
    robot: Robot,
    corpus: str | Path | None = None,
    cache: bool = True,
    progress: Callable[[int, int], None] | None = None,
) -> Learned:
    """Fit (or load from the cache) the learned pieces of ``robot`` on a corpus folder.

    A cache entry that is unreadable, edited or written for another key is fitted again and
    rewritten; the result's ``notes`` say so (as they say when the entry cannot be written).
    ``progress(k, n)`` is called after reading each of the ``n`` corpus files when fitting.
    """
    files = corpus_files(corpus)
    key = {
        "format": CACHE_VERSION,
        "robot": robot.name,
        "model": model_key(robot),
        "corpus": corpus_key(files),
    }
    path = entry_path(robot.name, key)
    notes = []
    if cache:
        arrays, problem = read_entry(path, key)
        if arrays is not None:
            try:
                return _from_arrays(arrays)
            except UNREADABLE as e:  # whole and of this key, yet not learned pieces
                problem = f"does not hold learned pieces ({type(e).__name__})"
        if problem is not None:
            notes.append(f"{path}: cache entry {problem}; fitted again")
    motions = []
    for f in files:
        motions.append(load_motion(f, rate=RATE))
        if progress is not None:
            progress(len(motions), len(files))
    learned = fit(robot, motions, tuple(f.name for f in files))
    if cache:
        failed = write_entry(path, _to_arrays(learned), key)
        notes += [failed] if failed else []
    return replace(learned, notes=tuple(notes))


def fit(robot: Robot, motions: Sequence[HumanMotion], names: tuple[str, ...] = ()) -> Learned:
    """Fit synergies and the Psi regressor on ``motions`` (and their mirror images); sample lambda_R."""
    corpus = []
    for m in motions:
        m = m if abs(m.rate - RATE) < 1e-6 else m.resample(RATE)
        if m.duration > 4 * TRIM:
            m = m.crop(TRIM, m.duration - TRIM)
        corpus += [m, m.mirrored()]
    arm = [j for s in SIDES for j in robot.arm_joints[s]]
    idx = np.asarray(robot.index(arm))
    moving = np.array([j not in robot.mapping.held_joints for j in arm])
    poses = [joint_mapping(robot, m)[:, idx] for m in corpus]
    synergies = fit_synergies(poses, 1.0 / RATE, idx, ~np.isfinite(robot.lower[idx]), moving)
    swivel, rms = SwivelPredictor.fit(*_body_frame_kinematics(corpus))
    return Learned(robot.name, names, synergies, swivel, float(rms), float(scale_factor(robot)))


def _body_frame_kinematics(motions: Sequence[HumanMotion]) -> tuple[np.ndarray, ...]:
    """Shoulder, elbow, wrist, TCP position (N, 2, 3) and TCP rotation (N, 2, 3, 3) of all frames,
    each frame expressed in its own heading frame (x along the shoulders, z up)."""
    parts = []
    for m in motions:
        k = forward_kinematics(m)
        frames = [shoulder_frame(s[0], s[1]) for s in k.shoulder]
        rot = np.stack([f[0] for f in frames])  # (T, 3, 3) world <- body
        origin = np.stack([f[1] for f in frames])
        local = [
            np.einsum("tji,tsj->tsi", rot, p - origin[:, None])
            for p in (k.shoulder, k.elbow, k.wrist, k.tcp_pos)
        ]
        local.append(np.einsum("tji,tsjk->tsik", rot, k.tcp_rot))
        parts.append(local)
    return tuple(np.concatenate([p[i] for p in parts]) for i in range(5))


def corpus_key(files: Sequence[Path]) -> str:
    """Hex digest of the human side of the learned pieces: the MMM model and the corpus files
    (names and contents)."""
    digest = hashlib.sha256()
    for path in (robots_dir() / "mjcf" / "mmm.xml", *files):
        try:
            data = Path(path).read_bytes()
        except OSError as e:
            raise MotionFormatError(path, f"cannot read the corpus file: {e.strerror or e}") from None
        digest.update(Path(path).name.encode())
        digest.update(data)
    return digest.hexdigest()


def _to_arrays(learned: Learned) -> dict[str, np.ndarray]:
    s = learned.synergies
    return {
        "robot": np.array(learned.robot),
        "corpus": np.array(learned.corpus, dtype=str),
        "swivel_coef": learned.swivel.coef,
        "swivel_rms": np.array(learned.swivel_rms),
        "scale": np.array(learned.scale),
        **{f"syn.{k}": getattr(s, k) for k in Synergies.__dataclass_fields__},
    }


def _from_arrays(a: dict[str, np.ndarray]) -> Learned:
    synergies = Synergies(**{k: a[f"syn.{k}"] for k in Synergies.__dataclass_fields__})
    return Learned(
        robot=str(a["robot"]),
        corpus=tuple(a["corpus"].tolist()),
        synergies=synergies,
        swivel=SwivelPredictor(a["swivel_coef"]),
        swivel_rms=float(a["swivel_rms"]),
        scale=float(a["scale"]),
    )
