"""What ``hlik robots`` lists, without compiling a model.

Importing MuJoCo and compiling the three bundled models costs about a second, most of
``hlik robots``. The summaries are cached as JSON keyed by the bytes of every file in ``robots/``
(descriptions and models), so an edited robot is loaded again; the first listing loads them all.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import asdict, dataclass
from pathlib import Path

from hlik.util.atomic import atomic_path
from hlik.util.errors import HlikError
from hlik.util.paths import cache_dir, robots_dir

FORMAT = "robots/1"


@dataclass(frozen=True)
class RobotSummary:
    """One bundled robot as listed: name, title, degrees of freedom, arm joints (left, right),
    extra joints by name and the number of unlimited joints."""

    name: str
    title: str
    dof: int
    arms: tuple[int, int]
    extra_joints: tuple[str, ...]
    unlimited: int


def robot_summaries() -> list[RobotSummary]:
    """The bundled robots' summaries, from the cache when every robot file is unchanged."""
    key = _key()
    try:
        path: Path | None = cache_dir() / f"robots-{key[:16]}.json"
    except HlikError:  # an unusable cache folder: list without it
        path = None
    if path is not None:
        try:
            stored = json.loads(path.read_text())
            if stored["key"] == key:
                return [_summary(entry) for entry in stored["robots"]]
        except (OSError, ValueError, KeyError, TypeError):
            pass  # no entry, or not one of ours: load the robots
    from hlik.robot.files import available_robots
    from hlik.robot.model import load_robot

    summaries = []
    for name in available_robots():
        r = load_robot(name)
        arms = (len(r.arm_joints["left"]), len(r.arm_joints["right"]))
        summaries.append(RobotSummary(r.name, r.title, r.dof, arms, tuple(r.extra_joints), len(r.unlimited)))
    if path is not None:
        try:
            with atomic_path(path) as tmp:
                tmp.write_text(json.dumps({"key": key, "robots": [asdict(s) for s in summaries]}))
        except OSError:
            pass  # listing does not need the cache
    return summaries


def _summary(entry: dict) -> RobotSummary:
    return RobotSummary(
        str(entry["name"]),
        str(entry["title"]),
        int(entry["dof"]),
        (int(entry["arms"][0]), int(entry["arms"][1])),
        tuple(str(j) for j in entry["extra_joints"]),
        int(entry["unlimited"]),
    )


def _key() -> str:
    digest = hashlib.sha256(FORMAT.encode())
    folder = robots_dir()
    for path in sorted(p for p in folder.rglob("*") if p.is_file()):
        digest.update(str(path.relative_to(folder)).encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()
