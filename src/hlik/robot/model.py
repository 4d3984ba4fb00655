"""Robot descriptions: an MJCF model plus ``robots/<name>.toml`` (arms, limits, home, mapping)."""

from __future__ import annotations

import sys
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import mujoco
import numpy as np

from hlik.errors import MotionFormatError, RobotError
from hlik.fk import site_poses
from hlik.human.motion import HumanMotion
from hlik.paths import robots_dir
from hlik.robot.mapping import JointMapping

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

SIDES = ("left", "right")
VISUAL_GROUP, COLLISION_GROUP = 1, 3  # MJCF geom groups: what a viewer draws, what collides
# Per arm: joint centres, the tracking TCP, and the frame whose velocity manipulability MAN^r reads
# (``{side}_{Robot.manipulability_site}``; robots/README.md).
SITES = ("shoulder", "elbow", "wrist", "tcp", "manipulability")
# Placement rules a robot description may name as its default (hlik.problem.placement).
PLACEMENT_RULES = ("reach", "mapped", "shoulders")


@dataclass(frozen=True, eq=False)
class Robot:
    """A robot hlik retargets to.

    Attributes:
        name: Short name (``armar3``, ``armar6``, ``dual_panda``).
        title: Display name.
        mjcf: Path of the MJCF model.
        model: The compiled MuJoCo model; ``qpos`` holds exactly the robot's joints.
        joint_names: (n,) joint names in ``qpos`` order.
        arm_joints: Side -> arm joint names, proximal to distal.
        extra_joints: Non-arm joints solved with the arms (ARMAR-III's hip).
        lower, upper: (n,) joint limits in rad; ``-inf``/``inf`` for unlimited joints.
        home: (n,) home configuration in rad.
        mapping: The MMM -> robot joint mapping of the arm joints.
        velocity_limit: (n,) largest joint speed in rad/s, aligned with ``joint_names``.
        velocity_source: Where ``velocity_limit`` comes from (datasheet, model file, assumption).
        manipulability_site: Site suffix of the manipulability frame (``{side}_<suffix>``).
        manipulability_joints: Non-arm joints that count in each arm's manipulability chain,
            proximal to the arm (ARMAR-III's hip, as in the paper's IK).
        placement: The placement rule used when none is given (``reach``, ``mapped``, ...; see
            :mod:`hlik.problem.placement`), chosen per robot from measurements (robots/README.md).
    """

    name: str
    title: str
    mjcf: Path
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
    manipulability_site: str = "tcp"
    manipulability_joints: tuple[str, ...] = ()
    placement: str = "reach"

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
            f"mjcf={self.mjcf.name!r})"
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


def available_robots() -> tuple[str, ...]:
    """Names of the bundled robots."""
    return tuple(sorted(p.stem for p in robots_dir().glob("*.toml")))


def load_robot(name: str) -> Robot:
    """Load a bundled robot by name, or a robot toml by path.

    Raises:
        hlik.errors.RobotError: unknown name, or a description inconsistent with its model.
    """
    path = Path(name) if name.endswith(".toml") else robots_dir() / f"{name}.toml"
    if not path.is_file():
        known = ", ".join(available_robots())
        raise RobotError(f"unknown robot {name!r}; choose one of: {known}")
    try:
        desc = tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as e:
        raise RobotError(f"{path}: invalid TOML: {e}") from None
    return _build(path, desc)


def _build(path: Path, desc: dict) -> Robot:
    try:
        mjcf = (path.parent / desc["mjcf"]).resolve()
        arms = {s: tuple(desc["arms"][s]["joints"]) for s in SIDES}
    except KeyError as e:
        raise RobotError(f"{path}: missing key {e}") from None
    try:
        model = mujoco.MjModel.from_xml_path(str(mjcf))
    except ValueError as e:
        raise RobotError(f"{mjcf}: cannot load MJCF: {e}") from None
    names = tuple(model.joint(i).name for i in range(model.njnt))
    if model.nq != model.njnt or np.any(model.jnt_type != mujoco.mjtJoint.mjJNT_HINGE):
        raise RobotError(f"{mjcf}: robot joints must all be hinges")
    extra = tuple(desc.get("extra_joints", ()))
    listed = [j for s in SIDES for j in arms[s]] + list(extra)
    unknown = [j for j in listed if j not in names]
    if unknown:
        raise RobotError(f"{path}: joints not in the model: {', '.join(unknown)}")
    manip = desc.get("manipulability", {})
    manip_site = str(manip.get("site", "tcp"))
    manip_joints = tuple(manip.get("joints", ()))
    for side in SIDES:
        for site in SITES:
            name = f"{side}_{manip_site if site == 'manipulability' else site}"
            if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, name) < 0:
                raise RobotError(f"{mjcf}: missing site {name}")
    arm_set = {j for s in SIDES for j in arms[s]}
    bad = [j for j in manip_joints if j not in names or j in arm_set]
    if bad:
        raise RobotError(f"{path}: [manipulability] joints must be non-arm model joints: {', '.join(bad)}")
    limited = model.jnt_limited.astype(bool)
    lower = np.where(limited, model.jnt_range[:, 0], -np.inf)
    upper = np.where(limited, model.jnt_range[:, 1], np.inf)
    home_table = desc.get("home", {})
    home = np.array([float(home_table.get(n, 0.0)) for n in names])
    velocity, velocity_source = _velocity_limits(path, desc, names)
    mapping = JointMapping.from_table(desc.get("mapping", {}))
    missing = [j for s in SIDES for j in arms[s] if j not in {m.joint for m in mapping.joints}]
    if missing:
        raise RobotError(f"{path}: no mapping for arm joint(s): {', '.join(missing)}")
    return Robot(
        name=desc.get("name", path.stem),
        title=desc.get("title", path.stem),
        mjcf=mjcf,
        model=model,
        joint_names=names,
        arm_joints=arms,
        extra_joints=extra,
        lower=lower,
        upper=upper,
        home=home,
        mapping=mapping,
        velocity_limit=velocity,
        velocity_source=velocity_source,
        manipulability_site=manip_site,
        manipulability_joints=manip_joints,
        placement=_placement_rule(path, desc),
    )


def _placement_rule(path: Path, desc: dict) -> str:
    rule = str(desc.get("placement", "reach"))
    if rule not in PLACEMENT_RULES:
        raise RobotError(f"{path}: placement {rule!r} is not one of {', '.join(PLACEMENT_RULES)}")
    return rule


def _velocity_limits(path: Path, desc: dict, names: tuple[str, ...]) -> tuple[np.ndarray, str]:
    """(n,) joint speed limits in rad/s from ``[velocity_limits]`` (every joint, positive, finite)."""
    table = dict(desc.get("velocity_limits", {}))
    source = str(table.pop("source", ""))
    missing = [n for n in names if n not in table]
    if missing:
        raise RobotError(f"{path}: [velocity_limits] has no value for: {', '.join(missing)}")
    unknown = [n for n in table if n not in names]
    if unknown:
        raise RobotError(f"{path}: [velocity_limits] names joints not in the model: {', '.join(unknown)}")
    try:
        limits = np.array([float(table[n]) for n in names])
    except (TypeError, ValueError):
        raise RobotError(f"{path}: [velocity_limits] values must be numbers in rad/s") from None
    if not np.all(np.isfinite(limits) & (limits > 0)):
        bad = [n for n, v in zip(names, limits) if not (np.isfinite(v) and v > 0)]
        raise RobotError(f"{path}: [velocity_limits] must be positive and finite: {', '.join(bad)}")
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
