"""Reading human motion files into a :class:`~hlik.human.motion.HumanMotion`."""

from __future__ import annotations

from pathlib import Path

from hlik.human.formats import motion_format
from hlik.human.mmm_format import read_mmm
from hlik.human.motion import HumanMotion


def load_motion(path: str | Path, rate: float | None = None) -> HumanMotion:
    """Read a motion file, optionally resampled to ``rate`` Hz.

    - ``.xml``: MMM 2.0 or legacy MMM;
    - ``.bvh``: a BVH skeleton with the usual joint names, fitted to the MMM model;
    - ``.toml``: a keypoint description (:mod:`hlik.human.keypoints`: joint positions in a
      ``.csv``/``.txt``/``.npy``/``.npz`` or a BVH with other names), fitted to the MMM model
      (:mod:`hlik.human.fit`).

    What the reader worked around (streams cut to a common span, gaps, poses outside the MMM
    ranges, lost markers, objects left out, detected units and axes) and the fit error are in the
    motion's ``notes``, one line each.

    Raises:
        hlik.util.errors.MotionFormatError: the file is missing, in a format hlik does not read
            (:func:`hlik.human.formats.motion_format`), malformed, inconsistent or implausible.
        hlik.util.errors.SettingsError: ``rate`` is outside 1-10000 Hz, or the resampled motion would
            have more than 10^6 frames.
    """
    path = Path(path)
    kind = motion_format(path)
    if kind == "mmm":
        motion = read_mmm(path)
    else:
        from hlik.human.fit import fit_mmm
        from hlik.human.keypoints import read_bvh, read_keypoints

        motion = fit_mmm(read_keypoints(path) if kind == "keypoints" else read_bvh(path))
    return motion if rate is None else motion.resample(rate)
