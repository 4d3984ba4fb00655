"""What the recordings look like and how they are chunked: layouts, colours, the metric panels' clusters
and palette, the chunk size and the score curves' time scale."""

from __future__ import annotations

import rerun as rr

from hlik.recording.layout import LAYOUTS as LAYOUTS  # re-exported
from hlik.recording.layout import SPACING as SPACING
from hlik.trajectory import Trajectory

SIDE_COLORS = {"left": (66, 133, 244), "right": (244, 140, 40)}
TARGET_COLORS = {"left": (120, 200, 255), "right": (255, 200, 120)}

_FILL = rr.components.FillMode.Solid

# Frames per chunk of columns. Each chunk is computed, sent and flushed before the next, so memory
# is bounded by it, not by the take. 4096 rows is where the viewer's store stops compacting
# (RERUN_CHUNK_MAX_ROWS); smaller chunks cost time, file size and footer memory per chunk.
CHUNK_FRAMES = 4096
# The time scale the score curves of the criteria of motion (MJE, MIS) are shown at, s: each frame's
# score flips between 0 and 1 with its jerk (metrics.Evaluation.curves says why); over 0.2 s the
# curve follows the motion as a viewer sees it, and still averages to m_i.
SCORE_WINDOW = 0.2


# The paper's clusters of the human-likeness criteria (formulas.md §10), one plot panel each; the
# three singletons share one. Criteria not named here (user-registered) share an "other" panel.
CLUSTERS = {
    "hand pose and arm posture": ("EEA", "SOA_x", "SOA_q", "EEA_r"),
    "joint space": ("HJL", "SYN", "HJA_r", "SYN_r"),
    "manipulability, jerk, minimum info": ("MAN_r", "MJE", "MIS"),
    "functional": ("fJLA", "fPOS", "fORI", "fPOS_off", "fORI_off"),
}

# Colours of the series of one panel, in order: Tableau 10, told apart at a glance. Joint k of
# either arm gets the same colour, so that the arms compare at a glance.
PALETTE = (
    (31, 119, 180),
    (255, 127, 14),
    (44, 160, 44),
    (214, 39, 40),
    (148, 103, 189),
    (140, 86, 75),
    (227, 119, 194),
    (127, 127, 127),
    (188, 189, 34),
    (23, 190, 207),
)


def score_window(trajectory: Trajectory) -> int:
    """:data:`SCORE_WINDOW` in frames of ``trajectory`` (odd, at least 1)."""
    dt = trajectory.period if trajectory.n_frames > 1 else SCORE_WINDOW
    return 2 * int(round(SCORE_WINDOW / dt / 2.0)) + 1
