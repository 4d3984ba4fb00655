"""Where the robot is drawn against the human (plain constants: the CLI checks ``--layout`` before
Rerun loads)."""

from __future__ import annotations

LAYOUTS = ("side", "overlay")  # side: the robot beside the human; overlay: on the human
SPACING = 1.2  # m between human and robot shoulders in the side-by-side layout
