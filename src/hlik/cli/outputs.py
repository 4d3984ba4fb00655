"""The files of ``hlik run``: checked before the solve, written together or not at all."""

from __future__ import annotations

import os
import re
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

from hlik.util.errors import HlikError

if TYPE_CHECKING:  # imported where used: `hlik --help` stays quick
    import numpy as np

    from hlik.metrics import Evaluation
    from hlik.robot.model import Robot
    from hlik.trajectory import Trajectory


def file_stem(*parts: str) -> str:
    """A file name stem from names read from files (motion, robot, stack): anything but letters,
    digits, ``.``, ``+``, ``-`` and ``_`` becomes ``_``, so no name can reach another folder."""
    return re.sub(r"[^\w.+-]", "_", "_".join(parts)).lstrip(".") or "out"


def check_outputs(rrd: Path, npz: Path, inputs: list, create: bool, force: bool = False) -> None:
    """Fail before solving, not after: the recording must be a ``.rrd`` whose folder is writable,
    neither output may be one of the ``inputs`` (paths or names; those that are no file are
    skipped), and neither may exist unless ``force``."""
    if rrd.is_dir():
        raise HlikError(f"{rrd}: is a folder, expected a .rrd file name")
    if rrd.suffix != ".rrd":
        raise HlikError(
            f"{rrd}: --out names the recording and must end in .rrd (the trajectory is written beside "
            f"it, as {rrd.with_suffix('.npz').name})"
        )
    read = [Path(p) for p in inputs if p is not None and Path(p).is_file()]
    for output in (rrd, npz):
        for source in read:
            if output.exists() and os.path.samefile(output, source) or output.resolve() == source.resolve():
                raise HlikError(f"{output}: is an input of this run ({source}); choose another --out")
    if not force:
        for output in (rrd, npz):
            if output.is_file() or output.is_symlink():
                raise HlikError(f"{output}: exists; pass --force to replace it, or --out to write elsewhere")
    folder = rrd.parent
    if create and not folder.exists():  # made when the outputs are written: a failed run leaves none
        folder = next(p for p in folder.parents if p.exists())
    if not folder.is_dir():
        raise HlikError(f"{rrd}: output folder {folder} does not exist")
    if npz.is_dir():
        raise HlikError(f"{npz}: is a folder, where the trajectory would be written")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise HlikError(f"{rrd}: output folder {folder} is not writable")


def write_outputs(
    npz: Path,
    rrd: Path,
    traj: Trajectory,
    robot: Robot,
    layout: str = "side",
    metrics: Mapping[str, np.ndarray] | None = None,
    evaluation: Evaluation | None = None,
    info: Mapping[str, str] | None = None,
) -> None:
    """Write the trajectory ``npz`` and its recording ``rrd`` together: both appear, or neither
    (:func:`hlik.util.atomic.atomic_paths`; a failed, interrupted or terminated write leaves no file).
    ``evaluation`` and ``info`` (setting -> text) go to the recording's result panel.

    Raises:
        HlikError: naming the file that could not be written (never the temporary).
    """
    from hlik.recording import write_recording
    from hlik.util.atomic import atomic_paths

    with _writing(npz, rrd):
        rrd.parent.mkdir(parents=True, exist_ok=True)
    with _writing(npz, rrd), atomic_paths(npz, rrd) as (npz_tmp, rrd_tmp):
        with _writing(npz):
            traj.save(npz_tmp)
        with _writing(rrd):
            write_recording(
                rrd_tmp, traj, robot, layout=layout, metrics=metrics, evaluation=evaluation, info=info
            )


@contextmanager
def _writing(*paths: Path) -> Iterator[None]:
    """Turn a failed write into one line naming the file (the first of ``paths`` unless the error
    names another)."""
    try:
        yield
    except OSError as e:
        named = Path(e.filename) if e.filename else None
        path = named if named in paths else paths[0]
        raise HlikError(f"{path}: cannot write ({e.strerror or e})") from None
    except RuntimeError as e:  # Rerun reports a failed write (full disk) as a RuntimeError
        raise HlikError(f"{paths[0]}: cannot write ({' '.join(str(e).split())})") from None
