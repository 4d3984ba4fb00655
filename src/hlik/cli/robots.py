"""``hlik robots``, ``hlik info`` and ``hlik calibrate``: the robots, a motion, a mapping."""

from __future__ import annotations

import sys
from typing import TYPE_CHECKING, Annotated

import typer
from rich.table import Table
from rich.text import Text

from hlik.util.paths import demo_motion_path

if TYPE_CHECKING:  # imported where used: `hlik --help` stays quick
    from hlik.robot.calibrate import Calibration
    from hlik.robot.mapping import JointMap
    from hlik.robot.model import Robot

from hlik.cli.app import (
    FLAG,
    MotionArg,
    console,
    one_line,
    print_table,
    warn,
)


def robots() -> None:
    """List the bundled robots with their degrees of freedom."""
    from hlik.robot.summary import robot_summaries

    table = Table("name", "robot", "DoF", "arms", "extra joints", "unlimited")
    with one_line():
        summaries = robot_summaries()
    for r in summaries:
        arms = " + ".join(map(str, r.arms))
        table.add_row(r.name, r.title, str(r.dof), arms, ", ".join(r.extra_joints) or "-", str(r.unlimited))
    print_table(table)


def info(motion: MotionArg = None) -> None:
    """Summarise a motion file: subject, duration, rate, joints, markers, objects."""
    from hlik.human.load import load_motion

    path = motion or demo_motion_path()
    with one_line():
        m = load_motion(path)
    warn(m.notes)
    table = Table(show_header=False, box=None)
    table.add_column(no_wrap=True)
    table.add_column(overflow="fold")
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
    print_table(table)


def calibrate(
    robot: Annotated[str, typer.Argument(help="Robot name (see `hlik robots`) or path of a robot .toml.")],
    toml: Annotated[
        bool,
        typer.Option("--toml", help="Print the mapping tables as TOML.", metavar=FLAG, show_default=False),
    ] = False,
    write: Annotated[
        bool,
        typer.Option(
            "--write",
            help="Write the mapping tables into the robot's .toml (replacing \\[mapping.*]).",
            metavar=FLAG,
            show_default=False,
        ),
    ] = False,
) -> None:
    """Derive the MMM -> robot joint mapping (paper Sec. III-A) and print it."""

    from hlik.robot.calibrate import calibrate as run_calibration
    from hlik.robot.calibrate import mapping_toml, write_mapping
    from hlik.robot.model import load_robot

    with one_line():
        r = load_robot(robot, need_mapping=False)
    cal = run_calibration(r)
    if toml:
        sys.stdout.write(mapping_toml(r, cal.mapping))
        return
    if write:
        assert r.description is not None  # load_robot always names the file it read
        write_mapping(r.description, mapping_toml(r, cal.mapping))
        console.print(f"wrote [mapping.left] and [mapping.right] to {r.description}")
        return
    _print_calibration(r, cal)


TCP_FRAME_OFF = 0.785  # rad (45 deg): a TCP frame further off the MMM hand's is warned about


def _print_calibration(r: Robot, cal: Calibration) -> None:
    """The derived mapping, its hand-frame error and dynamic offsets, and whether the TOML has it."""
    import numpy as np

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
            f"{round(m.b, 4) + 0.0:+.4f} ({round(m.b / np.pi, 3) + 0.0:+.3f}π)",  # + 0.0: no "-0.0000"
            off,
            f"{cal.score[m.joint]:.2f}",
        )
    print_table(table)
    res = ", ".join(f"{s} {np.degrees(v):.1f}°" for s, v in cal.residual.items())
    console.print(f"hand-frame error of the mapped default pose: {res}")
    turned = [f"{s} {np.degrees(v):.0f}°" for s, v in cal.residual.items() if v > TCP_FRAME_OFF]
    if turned:  # a joint mapping leaves a few degrees (ARMAR-6: 16); a site's axes, a quarter turn
        warn(
            [
                f"{r.description}: the TCP site's frame is turned {', '.join(turned)} from the MMM "
                "hand's in the mapped pose: its axes may not follow hlik's convention (z the approach, "
                "wrist to fingertips; x the palm normal; robots/README.md), and every run would turn "
                "that hand so"
            ]
        )
    offsets = [(m.joint, m.offset) for m in cal.mapping.joints if m.offset is not None]
    if offsets:
        found = ", ".join(f"{joint} {off.gain:+.3f}·{off.mmm}" for joint, off in offsets)
        console.print(f"dynamic offsets: {found} (paper, ARMAR-6 Sho2: +{0.55 / np.pi:.3f}·s_x)")
    stored = {m.joint: m for m in r.mapping.joints}
    same = all(_close(stored.get(m.joint), m) for m in cal.mapping.joints)
    where = f"robots/{r.name}.toml" if r.reference == r.name else r.description
    console.print(
        f"matches {where}"
        if same
        else Text.assemble((f"differs from {where}", "yellow"), " (print with --toml, store with --write)")
    )


def _close(a: JointMap | None, b: JointMap) -> bool:
    """Same joint mapping up to the printed precision (1e-3 rad, 1e-3 gain)."""
    if a is None:
        return False
    if (a.mmm != b.mmm and not a.a == 0 == b.a) or a.a != b.a or abs(a.b - b.b) >= 1e-3:
        return False
    if a.offset is None or b.offset is None:
        return a.offset is None and b.offset is None
    return a.offset.mmm == b.offset.mmm and abs(a.offset.gain - b.offset.gain) < 1e-3
