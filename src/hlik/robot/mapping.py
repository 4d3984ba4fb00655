"""The MMM -> robot joint mapping of the paper's Sec. III-A (Table I).

Every robot joint j is ``q_j = a_j * q_mmm + b_j`` of one MMM joint, plus an optional *dynamic*
offset ``gain * fold(q_src)`` that depends on another MMM joint (ARMAR-6's second shoulder joint in
the paper). ``a_j = 0`` holds the joint at ``b_j``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class DynamicOffset:
    """``gain * fold(q_src)`` with ``fold(x) = x`` below ``fold`` and ``2 fold - x`` above."""

    mmm: str
    gain: float
    fold: float = math.inf

    def __call__(self, q_src: np.ndarray) -> np.ndarray:
        return self.gain * np.where(q_src >= self.fold, 2.0 * self.fold - q_src, q_src)


@dataclass(frozen=True)
class JointMap:
    """How one robot joint follows the MMM model."""

    joint: str
    mmm: str | None
    a: float
    b: float
    offset: DynamicOffset | None = None

    @property
    def held(self) -> bool:
        """True where the joint follows no MMM joint: it stays at ``b`` whatever the human does."""
        return self.offset is None and (self.mmm is None or self.a == 0.0)

    def __call__(self, angles: Mapping[str, np.ndarray], n: int) -> np.ndarray:
        q = np.full(n, self.b)
        if self.mmm is not None and self.a != 0.0:
            q = q + self.a * angles[self.mmm]
        if self.offset is not None:
            q = q + self.offset(angles[self.offset.mmm])
        return q


@dataclass(frozen=True)
class JointMapping:
    """The mapping of all arm joints of a robot (both arms)."""

    joints: tuple[JointMap, ...]

    @property
    def mmm_joints(self) -> tuple[str, ...]:
        """MMM joints the mapping reads."""
        used = {m.mmm for m in self.joints if m.mmm and m.a != 0.0}
        used |= {m.offset.mmm for m in self.joints if m.offset}
        return tuple(sorted(used))

    @property
    def held_joints(self) -> tuple[str, ...]:
        """Robot joints the mapping holds fixed (ARMAR-6's clavicles, Panda joint 7)."""
        return tuple(m.joint for m in self.joints if m.held)

    def get(self, joint: str) -> JointMap:
        return next(m for m in self.joints if m.joint == joint)

    def apply(self, names: Sequence[str], angles: np.ndarray) -> dict[str, np.ndarray]:
        """Robot joint name -> (T,) angles, from MMM ``angles`` (T, k) with column ``names``."""
        angles = np.atleast_2d(angles)
        by_name = {n: angles[:, i] for i, n in enumerate(names)}
        return {m.joint: m(by_name, len(angles)) for m in self.joints}

    @classmethod
    def from_table(cls, table: Mapping[str, Mapping[str, Mapping]]) -> JointMapping:
        """Build from the ``[mapping.left]`` / ``[mapping.right]`` tables of a robot toml."""
        maps = []
        for side in ("left", "right"):
            for joint, entry in table.get(side, {}).items():
                off = entry.get("offset")
                maps.append(
                    JointMap(
                        joint=joint,
                        mmm=entry.get("mmm"),
                        a=float(entry.get("a", 0.0)),
                        b=float(entry.get("b", 0.0)),
                        offset=None
                        if off is None
                        else DynamicOffset(off["mmm"], float(off["gain"]), float(off.get("fold", math.inf))),
                    )
                )
        return cls(tuple(maps))
