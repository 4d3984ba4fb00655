"""SLSQP per frame on ARMAR-6, per criterion: analytic gradients against the paper's forward differences.

For the plain objective and for each human-likeness criterion alone (the study's correlation
approaches), SLSQP solves the same frames (1 s of the demo at 100 Hz, end-effector pose scenario,
the paper's weights) with ``gradients = analytic`` and ``fd``, interleaved (analytic, fd, fd,
analytic, ...) so that load on the shared cores hits both alike. Reported per line: CPU ms per
frame of each after the first frame (median over repeats), the speedup fd/analytic, the analytic
cost over the cheapest criterion's (the issue's target: within 2x), and the analytic first frame's
CPU ms and evaluations. The first frame is reported apart: it starts from the mapped human pose
without the smoothness terms and takes 80-200 evaluations (up to ``first_eval``) where a tracking
frame takes 3-4, so in a short run it would hide the per-frame cost. Last line: the worst
criterion's speedup. Run by hand: ``python bench/slsqp_gradients.py [--criteria SYN,EEA]
[--repeats 3] [--seconds 1]``.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

import numpy as np

import hlik
from hlik.criteria import registry
from hlik.criteria.learned import learn
from hlik.problem.problem import build_problem
from hlik.solvers.slsqp import SLSQPSettings, solve
from hlik.util.paths import demo_motion_path


def cpu_per_frame(problem, learned, criteria: tuple[str, ...], gradients: str) -> tuple[float, float, int]:
    """CPU seconds per frame after the first, the first frame's CPU seconds and its evaluations."""
    settings = SLSQPSettings(criteria=criteria, gradients=gradients)
    marks = [time.process_time()]
    result = solve(
        replace(problem, learned=learned), settings, progress=lambda k: marks.append(time.process_time())
    )
    cpu = np.diff(marks)
    return float(np.mean(cpu[1:])), float(cpu[0]), int(result.diagnostics.iterations[0])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--criteria", default=",".join(registry.human_likeness()))
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--seconds", type=float, default=1.0)
    args = parser.parse_args()
    robot = hlik.load_robot("armar6")
    motion = hlik.load_motion(demo_motion_path(), rate=100.0).crop(2.0, 2.0 + args.seconds)
    problem = build_problem(motion, robot)
    learned = learn(robot)
    cpu_per_frame(problem, learned, (), "analytic")  # warm-up: the first run in a process pays for imports
    rows = {}
    for name in ["none", *args.criteria.split(",")]:
        criteria = () if name == "none" else (name,)
        times: dict[str, list[tuple[float, float, int]]] = {"analytic": [], "fd": []}
        for r in range(args.repeats):
            order = ("analytic", "fd") if r % 2 == 0 else ("fd", "analytic")
            for gradients in order:
                times[gradients].append(cpu_per_frame(problem, learned, criteria, gradients))
        rows[name] = {k: np.median(np.array(v, dtype=float), axis=0) for k, v in times.items()}
    cheapest = min(r["analytic"][0] for n, r in rows.items() if n != "none")
    print(
        f"{'criterion':10s} {'analytic ms':>11s} {'fd ms':>8s} {'speedup':>8s} {'/cheapest':>9s} "
        f"{'first ms':>9s} {'first evals':>11s}"
    )
    for name, r in rows.items():
        a, f = r["analytic"], r["fd"]
        print(
            f"{name:10s} {1e3 * a[0]:11.2f} {1e3 * f[0]:8.2f} {f[0] / a[0]:8.1f} {a[0] / cheapest:9.1f} "
            f"{1e3 * a[1]:9.0f} {a[2]:11.0f}"
        )
    named = [n for n in rows if n != "none"]
    worst = min(named, key=lambda n: rows[n]["fd"][0] / rows[n]["analytic"][0])
    slowest = max(named, key=lambda n: rows[n]["analytic"][0])
    print(f"slowest criterion over the cheapest: {rows[slowest]['analytic'][0] / cheapest:.1f} ({slowest})")
    speedup = rows[worst]["fd"][0] / rows[worst]["analytic"][0]
    print(f"worst criterion speedup analytic/fd: {speedup:.1f} ({worst})")


if __name__ == "__main__":
    main()
