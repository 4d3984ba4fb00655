"""Study speedup on Ray: the same small study (demo motion, one robot, twelve QP/JV/OPT cells of
3 s) with 1 and with 2 Ray workers, fresh output folders, wall time of the cells. The cells are
sized like the default study's (3 s each, all three solvers): with eight 2 s QP/JV cells (7 s in
all) the start of a second worker ate the gain (1.0-1.2x).

Run by hand (needs ``pip install -e ".[study]"``): ``python bench/study_scaling.py [--robot armar6]``;
the last line is ``speedup 2 workers: X.X`` (wall time with 1 worker over 2; ideal 2.0 on this
machine's 2 cores, less the start-up of Ray and of each worker's robot).
"""

from __future__ import annotations

import argparse
import logging
import tempfile
import time
from pathlib import Path

import ray

from hlik.study.approaches import Approach
from hlik.study.runner import plan, prepare, run_cells
from hlik.util.paths import demo_motion_path

APPROACHES = tuple(Approach("qp", c) for c in ((), ("SYN",), ("HJA_r",), ("SOA_q",), ("SYN", "HJA_r")))
APPROACHES += tuple(Approach("jv", c) for c in ((), ("SYN",), ("HJA_r",)))
APPROACHES += tuple(Approach("slsqp", c) for c in ((), ("SYN",), ("HJA_r",), ("SYN", "HJA_r")))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", default="armar6")
    parser.add_argument("--seconds", type=float, default=3.0)
    args = parser.parse_args()
    cells = plan([demo_motion_path()], [args.robot], APPROACHES, args.seconds)
    prepare([args.robot])
    wall = {}
    for workers in (1, 2):
        ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False, logging_level=logging.ERROR)
        with tempfile.TemporaryDirectory() as folder:
            start = time.perf_counter()
            outcomes = run_cells(cells, Path(folder))  # on the Ray just started
            wall[workers] = time.perf_counter() - start
        failed = [o for o in outcomes if o.error]
        print(f"{workers} worker(s): {len(cells)} cells in {wall[workers]:.1f} s, {len(failed)} failed")
        ray.shutdown()
    print(f"speedup 2 workers: {wall[1] / wall[2]:.1f}")


if __name__ == "__main__":
    main()
