"""``hlik.metrics.evaluate`` on the demo trajectory (JM, ARMAR-6, 1265 frames): this checkout
against a baseline git revision, measured in one run.

Run by hand: ``python bench/evaluate_speed.py [--baseline REV] [--repeats 5]``. The baseline is
checked out into a temporary git worktree; both sides run in fresh subprocesses, interleaved, each
timing ``evaluate`` after one warm-up call (learned pieces cached). The last line is
``speedup current/baseline: X.X`` (ratio of medians). The machine has 2 shared cores: read the ratio.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SNIPPET = """
import time, numpy as np, hlik
try:
    from hlik.criteria.learned import learn
except ImportError:
    from hlik.learned import learn
from hlik.metrics import evaluate
robot = hlik.load_robot("armar6")
try:
    from hlik.human.demo import demo_motion
except ImportError:
    from hlik.demo import demo_motion
traj = hlik.retarget(demo_motion().resample(100.0), robot)
learned = learn(robot)
evaluate(traj, robot, learned)
times = []
for _ in range(3):
    start = time.perf_counter(); evaluate(traj, robot, learned); times.append(time.perf_counter() - start)
print(min(times))
"""


def timed(src: Path) -> float:
    env = dict(os.environ, PYTHONPATH=str(src))
    out = subprocess.run([sys.executable, "-c", SNIPPET], env=env, capture_output=True, text=True, check=True)
    return float(out.stdout.split()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline", default="80b42a9", help="git revision to compare with")
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        tree = Path(tmp) / "baseline"
        subprocess.run(
            ["git", "-C", str(ROOT), "worktree", "add", "-q", "--detach", str(tree), args.baseline],
            check=True,
        )
        try:
            results: dict[str, list[float]] = {"baseline": [], "current": []}
            for _ in range(args.repeats):
                results["baseline"].append(timed(tree / "src"))
                results["current"].append(timed(ROOT / "src"))
        finally:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(tree)], check=True)
    med = {k: float(np.median(v)) for k, v in results.items()}
    for k, v in med.items():
        print(f"{k:>8}: {1e3 * v:7.1f} ms per evaluate (median of {args.repeats} processes)")
    print(f"speedup current/baseline: {med['baseline'] / med['current']:.1f}")


if __name__ == "__main__":
    main()
