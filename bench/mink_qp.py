"""The QP on mink (this checkout) against the QP of a git revision: same takes, same stack, one run.

``--solver qp`` is :class:`~hlik.solvers.mink_ik.MinkSolver` over the QP's stack
(:func:`hlik.solvers.qp.build_solver`: every term a ``mink.Task``, mink's ``build_ik`` per step). Up
to ``d2f408f`` the QP assembled its own problem for daqp; this prints both on the same frames: CPU
time per frame (each robot's takes in one subprocess per checkout, the two alternating, median of
the repeats), steps per frame, m_hl, m_f, median fPOS and fORI, failed frames, and the largest
joint-angle difference between the two, with the look-ahead off (one pass, as the revisions
before it). Run by hand: ``python bench/mink_qp.py [--against d2f408f]
[--robots armar3,armar6,dual_panda] [--takes 2] [--seconds 2]``; the last line is ``ratio
mink/revision: X.XX`` (median CPU per frame; issue 29's target 1.3).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tarfile
import tempfile
from pathlib import Path

import numpy as np

from common import kit_takes

ROOT = Path(__file__).resolve().parents[1]
REPEATS = 3  # the two checkouts alternate: the machine's load moves both alike

# run in a subprocess with a checkout's src first on sys.path; prints one JSON line
CHILD = """
import json, sys, time
import numpy as np
import hlik
from hlik.criteria.functional import position_error, rotation_angle
from hlik.criteria.learned import learn
from hlik.metrics import evaluate
from hlik.problem.placement import placement_from_spec
from hlik.problem.scale import scale_subject
from hlik.solvers import get_solver
from hlik.solvers.stack_file import load_stack

name, criteria, seconds, takes = sys.argv[1], sys.argv[2].split(","), float(sys.argv[3]), sys.argv[4:]
robot = hlik.load_robot(name)
learned = learn(robot)
settings = load_stack("ee_pose").with_criteria(criteria).settings("qp")
if hasattr(settings, "preview_cost"):  # one pass, frame by frame, as every revision before it
    import dataclasses
    settings = dataclasses.replace(settings, preview_cost=0.0)
solver = get_solver("qp", settings)
cpu = frames = 0
out = {"steps": [], "m_hl": [], "m_f": [], "fpos": [], "fori": [], "failed": 0, "q": []}
for take in takes:
    motion = hlik.load_motion(take, rate=100.0)
    motion = scale_subject(motion.crop(1.0, min(1.0 + seconds, motion.duration)), robot)
    where = placement_from_spec(robot.placement, robot, motion)
    start = time.process_time()
    traj = hlik.retarget(motion, robot, solver, where, learned)
    cpu += time.process_time() - start
    frames += traj.n_frames
    ev = evaluate(traj, robot, learned)
    out["steps"] += traj.diagnostics.iterations[1:].tolist()
    out["m_hl"].append(ev.m_hl)
    out["m_f"].append(ev.m_f)
    out["fpos"] += position_error(traj.tcp_pos, traj.targets.pos).ravel().tolist()
    out["fori"] += rotation_angle(traj.tcp_rot, traj.targets.rot).ravel().tolist()
    out["failed"] += int(traj.diagnostics.n_failed)
    out["q"] += traj.q.tolist()
out["ms"] = 1e3 * cpu / frames
print(json.dumps(out))
"""


def checkout(revision: str, into: Path) -> Path:
    """The tree of ``revision`` (src, robots, tasks) unpacked into ``into``; its ``src``."""
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", revision], check=True, capture_output=True)
    path = into / "tree.tar"
    path.write_bytes(archive.stdout)
    with tarfile.open(path) as tar:
        tar.extractall(into, filter="data")
    return into / "src"


def run(src: Path, robot: str, criteria: str, seconds: float, takes: list[Path]) -> dict:
    """One checkout's QP over ``takes`` on ``robot``, in a fresh interpreter importing ``src``."""
    env = {**os.environ, "PYTHONPATH": str(src)}
    args = [sys.executable, "-c", CHILD, robot, criteria, str(seconds), *map(str, takes)]
    done = subprocess.run(args, check=True, capture_output=True, text=True, env=env, cwd=src.parent)
    return json.loads(done.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--against", default="d2f408f", help="git revision of the QP to compare with")
    parser.add_argument("--robots", default="armar3,armar6,dual_panda")
    parser.add_argument("--criteria", default="SYN,HJA_r")
    parser.add_argument("--takes", type=int, default=2)
    parser.add_argument("--seconds", type=float, default=2.0)
    args = parser.parse_args()
    takes = kit_takes(args.takes)
    print(
        f"{'robot':11s} {'qp':9s} {'ms/frame':>8s} {'steps':>6s} {'m_hl':>6s} {'m_f':>6s} "
        f"{'fPOS cm':>7s} {'fORI':>5s} {'failed':>6s}"
    )
    ratios = []
    with tempfile.TemporaryDirectory() as tmp:
        sources = {"mink": ROOT / "src", args.against: checkout(args.against, Path(tmp))}
        for robot in args.robots.split(","):
            ms: dict[str, list[float]] = {label: [] for label in sources}
            last: dict[str, dict] = {}
            for _ in range(REPEATS):
                for label, src in sources.items():
                    last[label] = out = run(src, robot, args.criteria, args.seconds, takes)
                    ms[label].append(out["ms"])
                    print(
                        f"{robot:11s} {label:9s} {out['ms']:8.2f} {np.mean(out['steps']):6.1f} "
                        f"{np.mean(out['m_hl']):6.3f} {np.mean(out['m_f']):6.3f} "
                        f"{100 * np.median(out['fpos']):7.2f} {np.degrees(np.median(out['fori'])):5.1f} "
                        f"{out['failed']:6d}",
                        flush=True,
                    )
            gap = np.max(np.abs(np.subtract(last["mink"]["q"], last[args.against]["q"])))
            ratios.append(float(np.median(ms["mink"]) / np.median(ms[args.against])))
            print(f"{robot:11s} ratio {ratios[-1]:.2f}, largest joint-angle difference {gap:.1e} rad")
    print(
        f"ratio mink/revision: {np.median(ratios):.2f} (per robot: {', '.join(f'{r:.2f}' for r in ratios)})"
    )


if __name__ == "__main__":
    main()
