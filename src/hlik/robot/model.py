"""Robot descriptions: a model file (MJCF or URDF) plus a TOML (arms, limits, home, mapping, sites)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING

import mujoco
import numpy as np

from hlik.human.kinematics import human_model
from hlik.robot.files import description_defaults, robot_toml
from hlik.robot.mapping import JointMapping
from hlik.robot.model_file import COLLISION_GROUP as COLLISION_GROUP  # re-exported: models' geom groups
from hlik.robot.model_file import VISUAL_GROUP as VISUAL_GROUP
from hlik.robot.model_file import ModelFile, compile_model
from hlik.util.errors import HlikError, MotionFormatError, RobotError
from hlik.util.paths import robots_dir
from hlik.util.spatial import site_poses
from hlik.util.tomlfile import did_you_mean, read_toml, unknown_key

if TYPE_CHECKING:  # scipy comes with the motion; `hlik robots` needs none
    from hlik.human.motion import HumanMotion


SIDES = ("left", "right")
# Per arm: joint centres, the tracking TCP, and the frame whose velocity manipulability MAN^r reads
# (``{side}_{Robot.manipulability_site}``; robots/README.md).
SITES = ("shoulder", "elbow", "wrist", "tcp", "manipulability")


@dataclass(frozen=True, eq=False)
class Robot:
    """A robot hlik retargets to.

    Attributes:
        name: Short name (``armar3``, ``armar6``, ``dual_panda``).
        title: Display name.
        model_file: The model file (MJCF or URDF) the model was compiled from.
        model: The compiled MuJoCo model; ``qpos`` holds exactly the robot's joints.
        joint_names: (n,) joint names in ``qpos`` order.
        arm_joints: Side -> arm joint names, proximal to distal.
        extra_joints: Non-arm joints solved with the arms (ARMAR-III's hip).
        lower, upper: (n,) joint limits in rad; ``-inf``/``inf`` for unlimited joints.
        home: (n,) home configuration in rad.
        mapping: The MMM -> robot joint mapping of the arm joints.
        velocity_limit: (n,) largest joint speed in rad/s, aligned with ``joint_names``.
        velocity_source: Where ``velocity_limit`` comes from (datasheet, model file, assumption).
        acceleration_limit: (n,) largest joint acceleration in rad/s^2 (``[acceleration_limits]``);
            ``inf`` where the description gives none.
        acceleration_source: Where ``acceleration_limit`` comes from; ``""`` if not given.
        jerk_limit: (n,) largest joint jerk in rad/s^3 (``[jerk_limits]``); ``inf`` where the
            description gives none.
        jerk_source: Where ``jerk_limit`` comes from; ``""`` if not given.
        effort_limit: (n,) largest joint torque in N m (``[effort_limits]`` or the URDF's
            ``<limit effort>``); ``inf`` where neither gives one.
        effort_source: Where ``effort_limit`` comes from; ``""`` if not given.
        manipulability_site: Site suffix of the manipulability frame (``{side}_<suffix>``).
        manipulability_joints: Non-arm joints that count in each arm's manipulability chain,
            proximal to the arm (ARMAR-III's hip, as in the paper's IK).
        placement: The placement rule used when none is given (``reach``, ``mapped``, ...; see
            :mod:`hlik.problem.placement`), chosen per robot from measurements (robots/README.md).
        description: The robot's TOML file.
        subject_scale: How the subject is scaled before retargeting, a factor or ``auto`` (the
            robot's arm length over the subject's; :mod:`hlik.problem.scale`). 1 for robots of a
            person's size, as in the paper.
    """

    name: str
    title: str
    model_file: Path
    model: mujoco.MjModel
    joint_names: tuple[str, ...]
    arm_joints: dict[str, tuple[str, ...]]
    extra_joints: tuple[str, ...]
    lower: np.ndarray
    upper: np.ndarray
    home: np.ndarray
    mapping: JointMapping
    velocity_limit: np.ndarray
    velocity_source: str = ""
    acceleration_limit: np.ndarray = None  # type: ignore[assignment]  # None: inf, set below
    acceleration_source: str = ""
    jerk_limit: np.ndarray = None  # type: ignore[assignment]
    jerk_source: str = ""
    effort_limit: np.ndarray = None  # type: ignore[assignment]
    effort_source: str = ""
    manipulability_site: str = "tcp"
    manipulability_joints: tuple[str, ...] = ()
    placement: str = "reach"
    description: Path | None = None
    subject_scale: float | str = 1.0

    def __post_init__(self):
        for key in ("acceleration_limit", "jerk_limit", "effort_limit"):
            if getattr(self, key) is None:
                object.__setattr__(self, key, np.full(len(self.joint_names), np.inf))

    @property
    def reference(self) -> str:
        """What :func:`load_robot` loads this robot from: its name if bundled, else its TOML's path."""
        if self.description is None or self.description.parent.resolve() == robots_dir().resolve():
            return self.name
        return str(self.description.resolve())

    @property
    def dof(self) -> int:
        return len(self.joint_names)

    @property
    def unlimited(self) -> tuple[str, ...]:
        return tuple(n for n, lo in zip(self.joint_names, self.lower) if np.isinf(lo))

    def index(self, joints: str | tuple[str, ...] | list[str]) -> int | np.ndarray:
        """Position(s) of joint(s) in the configuration vector."""
        if isinstance(joints, str):
            return self.joint_names.index(joints)
        return np.array([self.joint_names.index(j) for j in joints], dtype=int)

    def site_id(self, side: str, site: str) -> int:
        """MuJoCo id of ``{side}_{site}`` (site in :data:`SITES`; ``manipulability`` is the robot's)."""
        return self.model.site(f"{side}_{_suffix(self, site)}").id

    @cached_property
    def site_ids(self) -> np.ndarray:
        """(2, 5) MuJoCo ids of the sites, arms in :data:`SIDES` order, sites in :data:`SITES` order."""
        return np.array([[self.site_id(side, site) for site in SITES] for side in SIDES])

    @cached_property
    def manipulability_chain(self) -> np.ndarray:
        """(2, k) configuration indices of each arm's manipulability chain, proximal to distal."""
        return np.array([self.index(self.manipulability_joints + self.arm_joints[s]) for s in SIDES])

    def __repr__(self) -> str:
        arms = "+".join(str(len(self.arm_joints[s])) for s in SIDES)
        return (
            f"Robot(name={self.name!r}, title={self.title!r}, dof={self.dof}, arms={arms}, "
            f"extra={list(self.extra_joints)}, unlimited={len(self.unlimited)}, "
            f"model_file={self.model_file.name!r})"
        )


def self_contacts(
    robot: Robot, q: np.ndarray, data: mujoco.MjData | None = None
) -> list[tuple[str, str, float]]:
    """Pairs of robot bodies whose collision geoms touch or overlap at configuration ``q`` (n,).

    Collision geoms are the model's geoms with non-zero ``contype``/``conaffinity`` (group
    :data:`COLLISION_GROUP`); pairs the model excludes (adjacent links, a hand's own parts) never count.

    Returns:
        (body, body, signed distance in m, <= 0) per contact, deepest first.
    """
    model = robot.model
    data = mujoco.MjData(model) if data is None else data
    data.qpos[:] = q
    mujoco.mj_kinematics(model, data)
    mujoco.mj_collision(model, data)
    found = []
    for c in data.contact[: data.ncon]:
        b1, b2 = (model.body(model.geom_bodyid[g]).name for g in c.geom)
        found.append((b1, b2, float(c.dist)))
    return sorted(found, key=lambda c: c[2])


def _suffix(robot: Robot, site: str) -> str:
    return robot.manipulability_site if site == "manipulability" else site


def tcp_poses(robot: Robot, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(T, 2, 3) positions and (T, 2, 3, 3) rotations of both TCPs for joint angles (T, n)."""
    ids = np.array([robot.site_id(s, "tcp") for s in SIDES])
    return site_poses(robot.model, q, ids)


def load_robot(name: str, need_mapping: bool = True) -> Robot:
    """Load a bundled robot by name, or a robot toml by path.

    ``need_mapping=False`` accepts a description without its ``[mapping]`` tables (arm joints left
    out are held at home), for ``hlik calibrate`` to derive them.

    Raises:
        hlik.util.errors.RobotError: unknown name, an unreadable or malformed description (naming the
            file, the table and key), or one inconsistent with its model.
    """
    path = robot_toml(name)
    try:
        desc = read_toml(path, "robot")
    except HlikError as e:
        raise RobotError(str(e)) from None
    return _build(path, desc, need_mapping)


# the keys of a robot description and of its tables with fixed keys ([home], [sites], [mapping]
# and the limit tables are keyed by the model's joints and sites, checked where they are read)
KEYS = (
    "name", "title", "model", "mjcf", "extra_joints", "unlimited_joints", "placement", "subject_scale",
    "arms", "home", "manipulability", "velocity_limits", "acceleration_limits", "jerk_limits",
    "effort_limits", "mapping", "collision", "base", "sites", "package_dirs",
)  # fmt: skip
TABLE_KEYS = {
    "arms": SIDES,
    "arms.left": ("joints",),
    "arms.right": ("joints",),
    "manipulability": ("site", "joints"),
    "collision": ("exclude",),
    "base": ("pos", "rpy"),
}


def _check_keys(path: Path, desc: dict) -> None:
    """Refuse a key the description does not know, naming its table and the closest known key."""
    if problem := unknown_key(desc, KEYS, "the top-level table"):
        raise RobotError(f"{path}: {problem}")
    for where, allowed in TABLE_KEYS.items():
        table: object = desc
        for part in where.split("."):
            table = table.get(part, {}) if isinstance(table, dict) else {}
        if isinstance(table, dict) and (problem := unknown_key(table, allowed, f"[{where}]")):
            raise RobotError(f"{path}: {problem}")


def _build(path: Path, desc: dict, need_mapping: bool = True) -> Robot:
    _check_keys(path, desc)
    defaults = description_defaults(path, desc)
    source = _text(path, desc, "model", desc.get("mjcf"))  # ``mjcf`` is the key's former name
    arms, extra = _arm_joints(path, desc)
    listed = [j for s in SIDES for j in arms[s]] + list(extra)
    home_table = _table(path, desc, "home", required=False)
    home_angles = {j: _number(path, v, f"[home] {j}") for j, v in home_table.items()}
    collision = _table(path, desc, "collision", required=False)
    exclude = collision.get("exclude", [])
    if not isinstance(exclude, list):
        raise RobotError(f"{path}: [collision] exclude must be a list of [body, body] pairs, got {exclude!r}")
    compiled = compile_model(
        path,
        source,
        listed,
        home_angles,
        _table(path, desc, "base", required=False),
        _table(path, desc, "sites", required=False),
        exclude,
        {str(k): str(v) for k, v in _table(path, desc, "package_dirs", required=False).items()},
    )
    model, mjcf = compiled.model, compiled.path
    names = tuple(model.joint(i).name for i in range(model.njnt))
    if model.nq != model.njnt or np.any(model.jnt_type != mujoco.mjtJoint.mjJNT_HINGE):
        raise RobotError(f"{mjcf}: robot joints must all be hinges")
    manip_site, manip_joints = _manipulability(path, desc, model, mjcf, names, arms)
    limited = model.jnt_limited.astype(bool)
    _check_unlimited(path, desc, names, limited)
    _check_ranges(mjcf, model, names, limited)
    _check_chains(path, model, arms)
    lower = np.where(limited, model.jnt_range[:, 0], -np.inf)
    upper = np.where(limited, model.jnt_range[:, 1], np.inf)
    home = _home(path, home_angles, names, compiled.welded, lower, upper)
    limits = _motion_limits(path, desc, names, compiled)  # checked before the mapping, as the file reads
    _check_plausible(path, names, limits)
    _check_holds_home(path, model, home, names, limits["effort_limit"])
    mapping = _mapping(path, desc, names)
    missing = [j for s in SIDES for j in arms[s] if j not in {m.joint for m in mapping.joints}]
    if missing and need_mapping:
        raise RobotError(
            f"{path}: no mapping for arm joint(s): {', '.join(missing)}; "
            f"derive it with `hlik calibrate {path} --write`"
        )
    return Robot(
        name=defaults.name,
        title=_text(path, desc, "title", path.stem),
        model_file=mjcf,
        model=model,
        joint_names=names,
        arm_joints=arms,
        extra_joints=extra,
        lower=lower,
        upper=upper,
        home=home,
        mapping=mapping,
        **limits,
        manipulability_site=manip_site,
        manipulability_joints=manip_joints,
        placement=defaults.placement,
        description=path,
        subject_scale=defaults.subject_scale,
    )


def _motion_limits(path: Path, desc: dict, names: tuple[str, ...], compiled: ModelFile) -> dict:
    """The robot's per-joint speed (required), acceleration, jerk and effort limits with their
    sources, as :class:`Robot`'s fields (the model's own where the TOML gives none)."""
    fields: dict[str, object] = {}
    for what, key, unit, model_values, required in (
        ("velocity", "velocity_limits", "rad/s", compiled.velocity, True),
        ("acceleration", "acceleration_limits", "rad/s^2", {}, False),
        ("jerk", "jerk_limits", "rad/s^3", {}, False),
        ("effort", "effort_limits", "N m", compiled.effort, False),
    ):
        values, source = _joint_limits(path, desc, names, key, unit, model_values, required=required)
        fields[f"{what}_limit"], fields[f"{what}_source"] = values, source
    return fields


def _arm_joints(path: Path, desc: dict) -> tuple[dict[str, tuple[str, ...]], tuple[str, ...]]:
    """Each arm's joints (``[arms.<side>] joints``) and the extra (trunk) joints, none listed twice.

    Raises:
        RobotError: a table or list missing or malformed, or a joint listed twice.
    """
    arms_table = _table(path, desc, "arms")
    arms = {s: _names(path, _table(path, arms_table, s, f"arms.{s}"), "joints", f"arms.{s}") for s in SIDES}
    extra = _names(path, desc, "extra_joints", "the top level", required=False)
    listed = [j for s in SIDES for j in arms[s]] + list(extra)
    twice = sorted({j for j in listed if listed.count(j) > 1})
    if twice:
        raise RobotError(f"{path}: joints listed twice in [arms] and extra_joints: {', '.join(twice)}")
    return arms, extra


def _manipulability(
    path: Path,
    desc: dict,
    model: mujoco.MjModel,
    mjcf: Path,
    names: tuple[str, ...],
    arms: dict[str, tuple[str, ...]],
) -> tuple[str, tuple[str, ...]]:
    """The ``[manipulability]`` site and non-arm joints, with every site of :data:`SITES` checked in
    the compiled model.

    Raises:
        RobotError: a missing site, or a manipulability joint that is an arm's or not the model's.
    """
    manip = _table(path, desc, "manipulability", required=False)
    manip_site = _text(path, manip, "site", "tcp", "[manipulability] ")
    manip_joints = _names(path, manip, "joints", "[manipulability]", required=False)
    for side in SIDES:
        for site in SITES:
            site_name = f"{side}_{manip_site if site == 'manipulability' else site}"
            if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, site_name) < 0 and site == "manipulability":
                sites = [model.site(i).name.removeprefix(f"{side}_") for i in range(model.nsite)]
                hint = did_you_mean(manip_site, sites)
                raise RobotError(
                    f"{path}: [manipulability] site {manip_site!r}: {mjcf.name} has no site {site_name}{hint}"
                )
            if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, site_name) < 0:
                raise RobotError(f"{mjcf}: missing site {site_name}")
    arm_set = {j for s in SIDES for j in arms[s]}
    bad = [j for j in manip_joints if j not in names or j in arm_set]
    if bad:
        raise RobotError(f"{path}: [manipulability] joints must be non-arm model joints: {', '.join(bad)}")
    return manip_site, manip_joints


def _table(path: Path, desc: dict, key: str, where: str | None = None, required: bool = True) -> dict:
    """The table ``desc[key]`` (``[where]`` in messages); empty if absent and not ``required``."""
    if key not in desc:
        if required:
            raise RobotError(f"{path}: missing table [{where or key}]")
        return {}
    table = desc[key]
    if not isinstance(table, dict):
        raise RobotError(f"{path}: [{where or key}] must be a table, got {table!r}")
    return table


def _text(path: Path, desc: dict, key: str, default: str | None = None, where: str = "") -> str:
    value = desc.get(key, default)
    if value is None:
        raise RobotError(f"{path}: missing key {where}{key!r}")
    if not isinstance(value, str):
        raise RobotError(f"{path}: {where}{key} must be text, got {value!r}")
    return value


def _names(path: Path, desc: dict, key: str, where: str, required: bool = True) -> tuple[str, ...]:
    """A list of joint names ``desc[key]``."""
    if key not in desc and not required:
        return ()
    value = desc.get(key)
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise RobotError(f"{path}: {where} {key} must be a list of joint names, got {value!r}")
    return tuple(value)


def _number(path: Path, value: object, where: str) -> float:
    """A finite number from the description."""
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise RobotError(f"{path}: {where} must be a finite number, got {value!r}")
    return float(value)


def _home(
    path: Path,
    table: Mapping[str, float],
    names: tuple[str, ...],
    welded: Mapping[str, float],
    lower: np.ndarray,
    upper: np.ndarray,
) -> np.ndarray:
    """(n,) home configuration from the ``[home]`` angles (read by ``_number``; joints not listed at
    0), within the joint limits. ``[home]`` may also name welded joints: the angle they are welded at."""
    unknown = [j for j in table if j not in names and j not in welded]
    if unknown:
        raise RobotError(f"{path}: [home] names joints not in the model: {', '.join(unknown)}")
    home = np.array([table.get(n, 0.0) for n in names])
    outside = [n for n, v, lo, hi in zip(names, home, lower, upper) if not lo <= v <= hi]
    if outside:
        k = names.index(outside[0])
        raise RobotError(
            f"{path}: [home] {outside[0]} = {home[k]:g} rad is outside its limits "
            f"[{lower[k]:g}, {upper[k]:g}]"
        )
    return home


def _mapping(path: Path, desc: dict, names: tuple[str, ...]) -> JointMapping:
    """The ``[mapping.left]``/``[mapping.right]`` tables, checked entry by entry."""
    table = _table(path, desc, "mapping", required=False)
    human = human_model(1.0)
    mmm = [human.joint(i).name for i in range(human.njnt)]
    if problem := unknown_key(table, SIDES, "[mapping]"):
        raise RobotError(f"{path}: {problem}")
    for side in SIDES:
        for joint, entry in _table(path, table, side, f"mapping.{side}", required=False).items():
            where = f"[mapping.{side}] {joint}"
            if joint not in names:
                raise RobotError(f"{path}: {where}: not a joint of the model{did_you_mean(joint, names)}")
            if not isinstance(entry, dict):
                raise RobotError(f"{path}: {where} must be a table {{ mmm = ..., a = ..., b = ... }}")
            if problem := unknown_key(entry, ("mmm", "a", "b", "offset"), where):
                raise RobotError(f"{path}: {problem}")
            if "mmm" in entry and not isinstance(entry["mmm"], str):
                raise RobotError(f"{path}: {where} mmm must be an MMM joint name, got {entry['mmm']!r}")
            _check_mmm(path, entry.get("mmm"), f"{where} mmm", mmm)
            for key in ("a", "b"):
                _number(path, entry.get(key, 0.0), f"{where} {key}")
            offset = entry.get("offset")
            if offset is None:
                continue
            if not isinstance(offset, dict) or not isinstance(offset.get("mmm"), str):
                raise RobotError(f"{path}: {where} offset must be a table {{ mmm = ..., gain = ... }}")
            _check_mmm(path, offset["mmm"], f"{where} offset mmm", mmm)
            _number(path, offset.get("gain"), f"{where} offset gain")
            if "fold" in offset:
                fold = offset["fold"]
                if isinstance(fold, bool) or not isinstance(fold, int | float) or math.isnan(fold):
                    raise RobotError(f"{path}: {where} offset fold must be a number, got {fold!r}")
    return JointMapping.from_table(table)


def _check_mmm(path: Path, joint: str | None, where: str, known: Sequence[str]) -> None:
    """Refuse an MMM joint name the MMM model does not have (``known``, its joints), before any
    motion is read, which would otherwise be blamed for lacking it."""
    if joint is not None and joint not in known:
        hint = did_you_mean(joint, known)
        raise RobotError(f"{path}: {where}: {joint!r} is not a joint of the MMM model{hint}")


def _check_unlimited(path: Path, desc: dict, names: tuple[str, ...], limited: np.ndarray) -> None:
    """``unlimited_joints`` (none where absent) must be the model's joints without a range (the
    model decides; the list says what its author expects, so a model that disagrees is refused: a
    range left out by mistake would let the joint turn without a stop)."""
    listed = set(_names(path, desc, "unlimited_joints", "the top-level", required=False))
    free = {n for n, lim in zip(names, limited) if not lim}
    if free and "unlimited_joints" not in desc:
        wrong = ", ".join(sorted(free))
        raise RobotError(
            f"{path}: the model gives {wrong} no range; give it one, or list it in unlimited_joints "
            "if it turns without a stop"
        )
    if listed - free:
        wrong = ", ".join(sorted(listed - free))
        raise RobotError(f"{path}: unlimited_joints lists {wrong}, which the model limits (its range)")
    if free - listed:
        wrong = ", ".join(sorted(free - listed))
        raise RobotError(f"{path}: unlimited_joints leaves out {wrong}, which the model leaves unlimited")


# rad: no hinge of a robot arm turns further than this between its stops (a UR arm's +-2 pi); a
# range in degrees read as radians is wider (+-90 deg: 180 rad)
WIDEST_RANGE = 4.0 * np.pi + 1e-6


def _check_ranges(mjcf: Path, model: mujoco.MjModel, names: tuple[str, ...], limited: np.ndarray) -> None:
    """Every range in the model is at most :data:`WIDEST_RANGE` wide."""
    width = np.where(limited, model.jnt_range[:, 1] - model.jnt_range[:, 0], 0.0)
    if np.any(width > WIDEST_RANGE):
        j = int(np.argmax(width))
        lo, hi = model.jnt_range[j]
        raise RobotError(
            f"{mjcf}: joint {names[j]}: range {lo:g} to {hi:g} rad, {width[j]:.0f} rad wide: degrees in a "
            'model read in radians? (MJCF <compiler angle="degree">, URDF radians)'
        )


def _check_chains(path: Path, model: mujoco.MjModel, arms: dict[str, tuple[str, ...]]) -> None:
    """Each TCP site is moved by every joint of its arm in ``[arms]`` and by none of the other's."""
    for i, side in enumerate(SIDES):
        site = f"{side}_tcp"
        body, chain = int(model.site_bodyid[model.site(site).id]), set()
        while body > 0:
            chain |= {model.joint(j).name for j in np.flatnonzero(model.jnt_bodyid == body)}
            body = int(model.body_parentid[body])
        other = SIDES[1 - i]
        if crossed := [j for j in arms[other] if j in chain]:
            raise RobotError(
                f"{path}: [arms] {other}: {', '.join(crossed)} move {site}, the {side} TCP (the arms' "
                "joint lists swapped?)"
            )
        if missing := [j for j in arms[side] if j not in chain]:
            raise RobotError(
                f"{path}: [arms] {side}: {', '.join(missing)} do not move {site} (a TCP site on another "
                "body, or a joint of another chain)"
            )


# rad/s, rad/s^2: no robot arm's joint is faster (the G1's wrists, 37 rad/s, are the fastest here;
# datasheets give speeds in deg/s as often as in rad/s: a Panda's 150 deg/s written as 150 "rad/s")
FASTEST = {"velocity": 60.0, "acceleration": 2000.0}


def _check_plausible(path: Path, names: tuple[str, ...], limits: dict) -> None:
    """No speed or acceleration limit beyond :data:`FASTEST`: one written in degrees would let
    every joint move 57x faster than the robot can, with every check passing."""
    for what, bound in FASTEST.items():
        values, unit = limits[f"{what}_limit"], "rad/s" if what == "velocity" else "rad/s^2"
        fast = np.isfinite(values) & (values > bound)  # inf: none given
        if np.any(fast):
            j = int(np.argmax(np.where(fast, values, 0.0)))
            raise RobotError(
                f"{path}: [{what}_limits] {names[j]} = {values[j]:g} {unit} is faster than any robot "
                f"joint (at most {bound:g} {unit} taken as plausible): in degrees? write {unit}"
            )


def _check_holds_home(
    path: Path, model: mujoco.MjModel, home: np.ndarray, names: tuple[str, ...], effort: np.ndarray
) -> None:
    """Every effort limit holds the robot's home pose against gravity (the bundled robots need at
    most a third of theirs there): an effort written in another unit (kN m, 1000x too small) would
    leave the arms hanging at full torque in every frame."""
    data = mujoco.MjData(model)
    data.qpos[:] = home
    mujoco.mj_forward(model, data)
    ratio = np.abs(data.qfrc_bias) / effort
    if np.any(ratio > 1.0):
        j = int(np.argmax(ratio))
        raise RobotError(
            f"{path}: [effort_limits] {names[j]} = {effort[j]:g} N m cannot hold the home pose against "
            f"gravity ({abs(data.qfrc_bias[j]):.3g} N m there): the limits in N m?"
        )


def _joint_limits(
    path: Path,
    desc: dict,
    names: tuple[str, ...],
    key: str,
    unit: str,
    from_model: Mapping[str, float],
    required: bool,
) -> tuple[np.ndarray, str]:
    """(n,) per-joint limits in ``unit`` from the table ``[key]`` (every joint, positive, finite)
    and its ``source``; a joint the table leaves out takes the URDF's ``<limit>`` value if the model
    gives one. Absent and not ``required`` (nor in the model): infinite, source ``""``."""
    if key not in desc and not from_model and not required:
        return np.full(len(names), np.inf), ""
    table = dict(_table(path, desc, key, required=not from_model))
    source = str(table.pop("source", ""))
    inherited = [n for n in names if n not in table and n in from_model]
    table.update({n: from_model[n] for n in inherited})
    if inherited:
        attribute = key.removesuffix("_limits")  # velocity_limits: the URDF's <limit velocity>
        source = "; ".join(filter(None, [source, f"URDF <limit {attribute}> of {len(inherited)} joints"]))
    unknown = [n for n in table if n not in names]  # first: a misspelt name is also one missing
    if unknown:
        hint = did_you_mean(unknown[0], names)
        raise RobotError(f"{path}: [{key}] names joints not in the model: {', '.join(unknown)}{hint}")
    missing = [n for n in names if n not in table]
    if missing:
        raise RobotError(f"{path}: [{key}] has no value for: {', '.join(missing)}")
    bad_type = [n for n in names if isinstance(table[n], bool) or not isinstance(table[n], int | float)]
    if bad_type:
        n = bad_type[0]
        raise RobotError(f"{path}: [{key}] values must be numbers in {unit}, {n} is {table[n]!r}")
    limits = np.array([float(table[n]) for n in names])
    if not np.all(np.isfinite(limits) & (limits > 0)):
        bad = [n for n, v in zip(names, limits) if not (np.isfinite(v) and v > 0)]
        raise RobotError(f"{path}: [{key}] must be positive and finite: {', '.join(bad)}")
    return limits, source


def mapped_configuration(robot: Robot, motion: HumanMotion) -> np.ndarray:
    """(T, n) the MMM joint angles mapped through the robot's Table I mapping, not clipped.

    Joints the mapping does not cover (ARMAR-III's hip) stay at home.
    """
    missing = [j for j in robot.mapping.mmm_joints if j not in motion.joint_names]
    if missing:
        raise MotionFormatError(motion.source, f"motion lacks MMM joint(s) {', '.join(missing)}")
    q = np.tile(robot.home, (motion.n_frames, 1))
    for name, angles in robot.mapping.apply(motion.joint_names, motion.joints).items():
        q[:, robot.index(name)] = angles
    return q


def joint_mapping(robot: Robot, motion: HumanMotion) -> np.ndarray:
    """JM: :func:`mapped_configuration` clipped into the joint limits, as a robot controller would.

    Returns:
        (T, n) joint angles in ``robot.joint_names`` order.
    """
    return np.clip(mapped_configuration(robot, motion), robot.lower, robot.upper)
