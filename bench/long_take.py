"""Peak memory and output sizes of ``hlik run``'s stages on a long take (issue 15).

A real KIT take is played forward and backward (so the loop has no jumps), each pass at its own
speed (so it never repeats exactly), until it lasts ``--minutes``, written as an MMM file to a
temporary folder (never into the repository), and run through the stages of
``hlik run --solver jm`` on ARMAR-6: reading, resampling, learning the criteria, placing the robot,
retargeting, evaluating, saving the ``.npz`` and writing the recording.
Each stage's peak resident memory is measured exactly: the kernel's high-water mark (``VmHWM``) is
reset before the stage (``/proc/self/clear_refs``) and read after it. Rerun's writer allocates in
Rust, which ``tracemalloc`` cannot see, so resident memory is the measure.

Run by hand: ``python bench/long_take.py [--minutes 10] [--take Cut] [--rate 100]``. One line per
stage (peak MB, MB held after it, seconds); the last lines give the file sizes and
``peak MB: X`` over the whole run.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from collections.abc import Callable
from dataclasses import replace
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from common import DATA
from hlik.human.mmm_format import write_mmm
from hlik.human.motion import HumanMotion


def looped(motion: HumanMotion, seconds: float) -> HumanMotion:
    """``motion`` played forward, backward, forward ... until it lasts ``seconds``.

    Reversing every other pass keeps poses continuous at the seams. Each pass is played at its own
    speed (within 5 % of the recorded one), so that the long take never repeats exactly: repeated
    data would compress far better than a real long take does and flatter the file sizes.
    """
    n = motion.n_frames
    dt = float(np.median(np.diff(motion.times)))
    steps = int(round(seconds / dt)) + 1
    # frame index of each step of a forward-backward walk over 0 .. n-1 (the end frames not doubled)
    walk = np.arange(steps) % (2 * n - 2)
    index = np.where(walk < n, walk, 2 * n - 2 - walk)
    speed = 1.0 + 0.05 * np.sin(np.arange(steps) // (n - 1))  # one speed per pass
    times = motion.times[0] + np.concatenate([[0.0], np.cumsum(dt / speed[:-1])])
    return replace(motion.frames(index), name=f"{motion.name}_looped", times=times)


def _status(key: str) -> float:
    """A ``/proc/self/status`` memory field, MB."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith(key + ":"):
            return int(line.split()[1]) / 1024
    raise KeyError(key)


def stage(name: str, fn: Callable[[], Any], peaks: list[float]) -> Any:
    """Run ``fn``; print its peak and resulting resident memory (MB) and its wall time; append the
    peak to ``peaks``."""
    Path("/proc/self/clear_refs").write_text("5")  # resets VmHWM to the current RSS
    before = _status("VmRSS")
    start = time.perf_counter()
    out = fn()
    seconds = time.perf_counter() - start
    peak, after = _status("VmHWM"), _status("VmRSS")
    print(f"{name:<12} peak {peak:7.0f} MB (+{peak - before:6.0f})  held {after:7.0f} MB  {seconds:7.1f} s")
    peaks.append(peak)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--minutes", type=float, default=10.0)
    parser.add_argument("--take", default="Cut", help="KIT take name prefix (kit_bimanual/<take>_*.xml)")
    parser.add_argument("--rate", type=float, default=100.0)
    parser.add_argument("--keep", type=Path, help="write the .npz and .rrd here instead of a temp folder")
    args = parser.parse_args()

    import hlik
    from hlik.criteria.learned import learn
    from hlik.human.mmm_format import read_mmm
    from hlik.metrics import evaluate
    from hlik.problem.placement import placement_from_spec
    from hlik.recording import write_recording
    from hlik.retarget import retarget
    from hlik.solvers import get_solver

    (take,) = sorted((DATA / "kit_bimanual").glob(f"{args.take}_*.xml"))
    robot = hlik.load_robot("armar6")
    with tempfile.TemporaryDirectory() as tmp:
        source = take
        if args.minutes > 0:
            source = Path(tmp) / f"{take.stem}_{args.minutes:g}min.xml"
            write_mmm(looped(read_mmm(take), 60 * args.minutes), source)
        out, peaks = args.keep or Path(tmp), []
        out.mkdir(parents=True, exist_ok=True)
        print(f"{source.name}: {source.stat().st_size / 1e6:.1f} MB, ARMAR-6, jm, {args.rate:g} Hz")
        raw = stage("read", lambda: read_mmm(source), peaks)
        motion = stage("resample", partial(raw.resample, args.rate), peaks) if args.rate else raw
        del raw  # as hlik run, which keeps only the resampled motion
        print(f"{'':<12} {motion.n_frames} frames over {motion.duration:.1f} s")
        learned = stage("learn", lambda: learn(robot), peaks)
        where = stage("place", lambda: placement_from_spec(robot.placement, robot, motion), peaks)
        jm = get_solver("jm")
        traj = stage("retarget", lambda: retarget(motion, robot, jm, where), peaks)
        ev = stage("evaluate", lambda: evaluate(traj, robot, learned), peaks)
        rrd = out / f"{source.stem}.rrd"
        npz = stage("save npz", lambda: traj.save(rrd.with_suffix(".npz")), peaks)
        stage("recording", lambda: write_recording(rrd, traj, robot, metrics=ev.curves()), peaks)
        print(f"npz {npz.stat().st_size / 1e6:.1f} MB, rrd {rrd.stat().st_size / 1e6:.1f} MB")
        print(f"peak MB: {max(peaks):.0f}")


if __name__ == "__main__":
    main()
