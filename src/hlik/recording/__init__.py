"""Rerun recordings of a retargeted motion: robot and human, targets, joint and error curves.

Entity tree::

    /world/human/bodies/<body>      human model (MJCF geometry), world frame
    /world/human/hand_paths         recorded hand (TCP) paths
    /world/objects/<object>         scene objects as boxes fitted to their markers
    /world/labels/<object>          each object's name (``true_`` dropped) just above its box
    /world/placement                the robot base as drawn (x and forward arrows), labelled with its rule
    /world/robot                    placement (and side-by-side offset) of the robot base
    /world/robot/bodies/<body>      robot model (MJCF geometry), base frame
    /world/robot/target_paths       hand targets; /world/robot/targets/<side> the current target frame
    /world/robot/tcp_paths          robot TCP paths; /world/robot/tcp/<side> the current TCP frame
    /plots/joints/<joint>           joint angles, rad (m for a sliding joint)
    /plots/fPOS/<side>, /plots/fORI/<side>   tracking errors, m and rad
    /plots/fPOS_off, /plots/fORI_off     relative-pose errors (paper Eqs. 3-4), relative runs only
    /plots/metrics/<criterion>      per-frame scores f_x0(h(t)) of the criteria, in [0, 1]
    /plots/unified/{m_hl,m_f}       per-frame weighted scores whose means are m_hl and m_f
    /plots/posture/<who>_<side>_{elbow,hand}, /plots/posture/<who>_lean   posture measures of the
                                    robot and the subject (hlik.posture): elbow and hand ahead of the
                                    shoulders in arm lengths, trunk lean in rad
    /plots/solver/{iterations,failed}   solver diagnostics per frame
    /result                         markdown: motion, robot, solver, settings, scores, diagnostics
    /result/json                    the ``hlik evaluate --json`` object of the same evaluation

Timelines: ``frame`` (index) and ``time`` (seconds). Everything time-varying goes through
``send_columns``, chunk by chunk of frames (:data:`CHUNK_FRAMES`), so that a long take needs no
more memory than a short one to draw; log time is disabled so the same input gives the same file.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from hlik.util.lazy import lazy_getattr

if TYPE_CHECKING:
    from hlik.recording.panel import summary
    from hlik.recording.scene import object_label
    from hlik.recording.style import CHUNK_FRAMES, LAYOUTS, SCORE_WINDOW, score_window
    from hlik.recording.view import (
        ASPECT,
        FRAME_TAN,
        Camera,
        blueprint,
        joint_groups,
        robot_camera,
        scene_camera,
    )
    from hlik.recording.write import write_recording

# Imported on first use (PEP 562): `--layout` is checked before Rerun loads.
_WHERE = {
    "summary": "hlik.recording.panel",
    "object_label": "hlik.recording.scene",
    "CHUNK_FRAMES": "hlik.recording.style",
    "LAYOUTS": "hlik.recording.layout",
    "SCORE_WINDOW": "hlik.recording.style",
    "score_window": "hlik.recording.style",
    "ASPECT": "hlik.recording.view",
    "FRAME_TAN": "hlik.recording.view",
    "Camera": "hlik.recording.view",
    "blueprint": "hlik.recording.view",
    "joint_groups": "hlik.recording.view",
    "robot_camera": "hlik.recording.view",
    "scene_camera": "hlik.recording.view",
    "write_recording": "hlik.recording.write",
}
__getattr__ = lazy_getattr(__name__, _WHERE, globals())

__all__ = [
    "ASPECT",
    "CHUNK_FRAMES",
    "FRAME_TAN",
    "LAYOUTS",
    "SCORE_WINDOW",
    "Camera",
    "blueprint",
    "joint_groups",
    "object_label",
    "robot_camera",
    "scene_camera",
    "score_window",
    "summary",
    "write_recording",
]
