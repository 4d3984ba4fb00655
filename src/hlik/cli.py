"""The ``hlik`` command line. Bad input ends in one line on stderr and exit code 2."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated

import numpy as np
import typer
from rich.console import Console
from rich.table import Table

from hlik.errors import HlikError
from hlik.paths import demo_motion_path

app = typer.Typer(
    help="hlik: human-like bimanual motion retargeting (MMM human -> ARMAR-III, ARMAR-6, 2-Panda).",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
console = Console()

MotionArg = Annotated[
    Path | None, typer.Argument(help="MMM motion file (default: the bundled demo).", show_default=False)
]


def _fail(err: HlikError) -> None:
    Console(stderr=True).print(f"[red]error:[/red] {err}", highlight=False, soft_wrap=True)
    raise typer.Exit(2)


@app.command()
def robots() -> None:
    """List the bundled robots with their degrees of freedom."""
    from hlik.robot import available_robots, load_robot

    table = Table("name", "robot", "DoF", "arms", "extra joints", "unlimited")
    for name in available_robots():
        r = load_robot(name)
        arms = " + ".join(str(len(r.arm_joints[s])) for s in ("left", "right"))
        table.add_row(
            name, r.title, str(r.dof), arms, ", ".join(r.extra_joints) or "-", str(len(r.unlimited))
        )
    console.print(table)


@app.command()
def info(motion: MotionArg = None) -> None:
    """Summarise a motion file: subject, duration, rate, joints, markers, objects."""
    from hlik.motion import load_motion

    path = motion or demo_motion_path()
    try:
        m = load_motion(path)
    except HlikError as e:
        _fail(e)
    table = Table(show_header=False, box=None)
    table.add_row("file", str(path))
    table.add_row("motion", m.name)
    table.add_row("subject", f"{m.height:.2f} m" + (f", {m.mass:g} kg" if m.mass else ""))
    table.add_row("frames", f"{m.n_frames} over {m.duration:.2f} s at {m.rate:.1f} Hz")
    arm = [n for n in m.joint_names if n[:2] in ("LS", "LE", "LW", "RS", "RE", "RW")]
    table.add_row("joints", f"{len(m.joint_names)} ({len(arm)} arm)")
    table.add_row(
        "markers", f"{len(m.markers)}" + (f": {', '.join(sorted(m.markers)[:8])} ..." if m.markers else "")
    )
    table.add_row("objects", ", ".join(m.objects) or "-")
    console.print(table)


@app.command()
def calibrate(
    robot: Annotated[str, typer.Argument(help="Robot name (see `hlik robots`).")],
    toml: Annotated[bool, typer.Option("--toml", help="Print the [mapping] tables as TOML.")] = False,
) -> None:
    """Derive the MMM -> robot joint mapping (paper Sec. III-A) and print it."""
    from hlik.calibrate import calibrate as run_calibration
    from hlik.calibrate import mapping_toml
    from hlik.robot import load_robot

    try:
        r = load_robot(robot)
    except HlikError as e:
        _fail(e)
    cal = run_calibration(r)
    if toml:
        sys.stdout.write(mapping_toml(r, cal.mapping))
        return
    table = Table(
        "robot joint",
        "MMM joint",
        "a",
        "b (rad)",
        "dynamic offset",
        "match",
        title=f"{r.title}: q_robot = a·q_mmm + b (+ offset)",
    )
    for m in cal.mapping.joints:
        off = f"{m.offset.gain:+.4f}·{m.offset.mmm}" if m.offset else ""
        table.add_row(
            m.joint,
            m.mmm or "(held)",
            f"{m.a:+.0f}",
            f"{m.b:+.4f} ({m.b / np.pi:+.3f}π)",
            off,
            f"{cal.score[m.joint]:.2f}",
        )
    console.print(table)
    res = ", ".join(f"{s} {np.degrees(v):.1f}°" for s, v in cal.residual.items())
    console.print(f"hand-frame error of the mapped default pose: {res}")
    stored = r.mapping
    same = all(_close(stored.get(m.joint), m) for m in cal.mapping.joints)
    console.print(
        "matches robots/" + f"{r.name}.toml"
        if same
        else f"[yellow]differs from robots/{r.name}.toml[/yellow] (print with --toml)"
    )


def _close(a, b) -> bool:
    off_a = (a.offset.mmm, a.offset.gain) if a.offset else None
    off_b = (b.offset.mmm, b.offset.gain) if b.offset else None
    return (
        (a.mmm == b.mmm or a.a == 0 == b.a)
        and a.a == b.a
        and abs(a.b - b.b) < 1e-3
        and (off_a == off_b or (off_a and off_b and off_a[0] == off_b[0] and abs(off_a[1] - off_b[1]) < 1e-3))
    )


def main() -> None:  # pragma: no cover
    app()
