"""Reading human motion files into a :class:`~hlik.human.motion.HumanMotion`."""

from __future__ import annotations

from pathlib import Path

from hlik.human.mmm_format import read_mmm
from hlik.human.motion import HumanMotion


def load_motion(path: str | Path, rate: float | None = None) -> HumanMotion:
    """Read an MMM motion file (MMM 2.0 or legacy), optionally resampled to ``rate`` Hz.

    What the reader worked around (streams cut to a common span, gaps, poses outside the MMM
    ranges, lost markers, objects left out) is in the motion's ``notes``, one line each.

    Raises:
        hlik.errors.MotionFormatError: the file is missing, malformed, inconsistent or implausible.
        hlik.errors.SettingsError: ``rate`` is outside 1-10000 Hz, or the resampled motion would
            have more than 10^6 frames.
    """
    motion = read_mmm(Path(path))
    return motion if rate is None else motion.resample(rate)
