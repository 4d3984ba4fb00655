"""How fast a usage or input mistake gets its one-line error: ten mistakes a new user makes, each
run as ``python -m hlik ...`` (the console script adds the launcher's own start-up), against
``python -c "import hlik.cli"`` in the same run (the floor: Python starting and importing the
command line, typer and rich).

Target (issue 32): every mistake answered in <= 0.5 s, exit 2, one line, before any heavy library
(NumPy, MuJoCo, SciPy, Rerun) loads. Run by hand: ``python bench/cli_errors.py [--repeat 5]``.
Prints each mistake's median wall time, its ratio to the floor, its exit code and its message.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from common import DATA

MISTAKES = {
    "unknown robot": ["run", "--robot", "armar7"],
    "missing motion file": ["run", "no_such_take.xml"],
    "unknown criterion": ["run", "--solver", "qp", "--criteria", "SYNN"],
    "negative rate": ["run", "--rate", "-1"],
    "unknown solver": ["run", "--solver", "qpp"],
    "unknown layout": ["run", "--layout", "sideways"],
    "bad placement": ["run", "--placement", "nan,0,0"],
    "CMU .amc take": ["run", str(DATA / "cmu" / "01_01.amc")],
    "HDM05 .c3d take": ["run", str(DATA / "hdm05" / "HDM_dg_06-03_03_120.c3d")],
    "missing trajectory": ["evaluate", "no_such_run.npz"],
    "export, missing trajectory": ["export", "no_such_run.npz", "--format", "csv"],
    "replay, missing trajectory": ["replay", "no_such_run.npz"],
    "study, unknown robot": ["study", "--robots", "armar7"],
    "bad stack-file value": ["run", "--stack", "bad_stack.toml"],  # written into the working folder
    "default output exists": ["run", "--solver", "jm"],  # recordings/demo_pour_wipe_armar6_jm.rrd, written
    "unknown export format": ["run", "--export", "parquet"],
    "negative subject scale": ["run", "--scale", "-2"],
    "export, unknown format": ["export", "recordings/demo_pour_wipe_armar6_jm.npz", "--format", "xlsx"],
}
HEAVY = ("numpy", "mujoco", "scipy", "rerun")


def timed(args: list[str], cwd: str) -> tuple[float, int, str]:
    """Wall time (s), exit code and last stderr line of ``python -m hlik ARGS``."""
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "hlik", *args], cwd=cwd, capture_output=True, text=True)
    wall = time.perf_counter() - start
    lines = (done.stderr or done.stdout).strip().splitlines()
    return wall, done.returncode, lines[-1] if lines else ""


def _floor(cwd: str) -> float:
    """Wall time (s) of starting Python and importing the command line."""
    start = time.perf_counter()
    subprocess.run([sys.executable, "-c", "import hlik.cli"], cwd=cwd, check=True)
    return time.perf_counter() - start


def heavy_imports(args: list[str], cwd: str) -> list[str]:
    """The heavy libraries ``python -m hlik ARGS`` imported before it exited."""
    code = (
        "import sys, runpy\n"
        "try:\n    runpy.run_module('hlik', run_name='__main__')\n"
        "except SystemExit:\n    pass\n"
        f"print(','.join(m for m in {HEAVY!r} if m in sys.modules), file=sys.__stdout__)"
    )
    done = subprocess.run([sys.executable, "-c", code, *args], cwd=cwd, capture_output=True, text=True)
    return (
        [m for m in done.stdout.strip().splitlines()[-1:][0].split(",") if m] if done.stdout.strip() else []
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    opts = parser.parse_args()
    with tempfile.TemporaryDirectory() as cwd:  # nothing to find or write in the working folder
        (Path(cwd) / "bad_stack.toml").write_text("[qp.gamma]\nHJA_r = 1e300\n")
        # a real run's pair: the default output that exists, the trajectory to export
        subprocess.run(
            [sys.executable, "-m", "hlik", "run", "--solver", "jm"], cwd=cwd, check=True, capture_output=True
        )
        floor = statistics.median(_floor(cwd) for _ in range(opts.repeat))
        print(f'floor (python -c "import hlik.cli"): {floor:.2f} s, median of {opts.repeat}')
        print(f"{'mistake':28s} {'median s':>8s} {'/floor':>6s} exit  heavy imports  message")
        slow = 0
        for name, args in MISTAKES.items():
            runs = [timed(args, cwd) for _ in range(opts.repeat)]
            wall = statistics.median(r[0] for r in runs)
            code, message = runs[-1][1], runs[-1][2]
            heavy = ",".join(heavy_imports(args, cwd)) or "-"
            slow += wall > 0.5
            print(f"{name:28s} {wall:8.2f} {wall / floor:6.2f} {code:4d}  {heavy:13s}  {message[:90]}")
        print(f"{slow} of {len(MISTAKES)} over 0.5 s")


if __name__ == "__main__":
    main()
