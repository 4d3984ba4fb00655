"""SLSQP per frame on ARMAR-6, per criterion: analytic gradients against the paper's forward differences.

For the plain objective and for each human-likeness criterion alone (the study's correlation
approaches), SLSQP solves the same frames (0.5 s of the demo at 100 Hz, end-effector pose scenario,
the paper's weights) with ``gradients = analytic`` and ``fd``, interleaved (analytic, fd, fd,
analytic, ...) so that load on the shared cores hits both alike. Reported per line: CPU ms per
frame of each (median over repeats), the speedup fd/analytic, and the analytic cost over the
cheapest criterion's (the issue's target: within 2x). Last line: the worst criterion's speedup.
Run by hand: ``python bench/slsqp_gradients.py [--criteria SYN,EEA] [--repeats 2]``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import hlik
from hlik.criteria import registry
from hlik.criteria.learned import learn
from hlik.paths import demo_motion_path
from hlik.problem.problem import build_problem
from hlik.solvers.slsqp import SLSQPSettings, solve


def cpu_per_frame(problem, learned, criteria: tuple[str, ...], gradients: str) -> float:
    """CPU seconds per frame of one SLSQP run (all frames; the first starts from the human pose)."""
    settings = SLSQPSettings(criteria=criteria, gradients=gradients)
    start = time.process_time()
    solve(problem, settings, learned)
    return (time.process_time() - start) / problem.n_frames


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--criteria", default=",".join(registry.human_likeness()))
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--seconds", type=float, default=0.5)
    args = parser.parse_args()
    robot = hlik.load_robot("armar6")
    motion = hlik.load_motion(demo_motion_path(), rate=100.0).crop(2.0, 2.0 + args.seconds)
    problem = build_problem(motion, robot)
    learned = learn(robot)
    rows = {}
    for name in ["none", *args.criteria.split(",")]:
        criteria = () if name == "none" else (name,)
        times: dict[str, list[float]] = {"analytic": [], "fd": []}
        for r in range(args.repeats):
            order = ("analytic", "fd") if r % 2 == 0 else ("fd", "analytic")
            for gradients in order:
                times[gradients].append(cpu_per_frame(problem, learned, criteria, gradients))
        rows[name] = {k: float(np.median(v)) for k, v in times.items()}
    cheapest = min(r["analytic"] for n, r in rows.items() if n != "none")
    print(f"{'criterion':10s} {'analytic ms':>11s} {'fd ms':>8s} {'speedup':>8s} {'/cheapest':>9s}")
    for name, r in rows.items():
        print(
            f"{name:10s} {1e3 * r['analytic']:11.2f} {1e3 * r['fd']:8.2f} {r['fd'] / r['analytic']:8.1f} "
            f"{r['analytic'] / cheapest:9.1f}"
        )
    worst = min((n for n in rows if n != "none"), key=lambda n: rows[n]["fd"] / rows[n]["analytic"])
    slowest = max((n for n in rows if n != "none"), key=lambda n: rows[n]["analytic"])
    print(f"slowest criterion over the cheapest: {rows[slowest]['analytic'] / cheapest:.1f} ({slowest})")
    print(f"worst criterion speedup analytic/fd: {rows[worst]['fd'] / rows[worst]['analytic']:.1f} ({worst})")


if __name__ == "__main__":
    main()
