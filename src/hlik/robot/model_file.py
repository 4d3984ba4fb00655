"""Compiling a robot's model file (MJCF or URDF) into the model hlik solves on, with ``mujoco.MjSpec``.

A robot description (``robots/<name>.toml`` or any TOML by path) may point at a model authored
elsewhere: a URDF with ``package://`` meshes, an MJCF from MuJoCo Menagerie. Its file is never
changed; what hlik needs is edited into the compiled copy:

- ``[base]``: the pose of the model's root in hlik's robot frame (x = right, y = forward, z = up,
  floor at z = 0). A URDF (REP 103: x forward) needs ``rpy = [0, 0, pi/2]``.
- joints that are neither arm nor extra joints (legs, head, fingers) are welded at their ``[home]``
  angle (0 if none), so that the configuration holds exactly the robot's solved joints;
- ``[sites]``: the shoulder, elbow, wrist, TCP and manipulability frames as a body plus an offset;
- geoms that collide go to group :data:`COLLISION_GROUP`, the others to :data:`VISUAL_GROUP`; body
  pairs that touch at the home pose (links that overlap by construction) are excluded from
  collision, with the pairs of ``[collision] exclude``.
"""

from __future__ import annotations

import math
import os
import sys
import sysconfig
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
from scipy.spatial.transform import Rotation

from hlik.errors import RobotError

VISUAL_GROUP, COLLISION_GROUP = 1, 3  # MJCF geom groups: what a viewer draws, what collides
PACKAGE = "package://"


@dataclass(frozen=True)
class ModelFile:
    """A compiled model and what its file said beyond MuJoCo.

    Attributes:
        path: The model file (MJCF or URDF), resolved.
        model: The compiled model; ``qpos`` holds the kept joints only.
        welded: Joint name -> angle (rad) of the joints welded into their bodies.
        velocity: Joint name -> speed limit (rad/s) a URDF gives (``<limit velocity>``); empty for MJCF.
    """

    path: Path
    model: mujoco.MjModel
    welded: Mapping[str, float]
    velocity: Mapping[str, float]


def resolve_package(uri: str, toml: Path, package_dirs: Mapping[str, str]) -> Path:
    """The file a ``package://NAME/rest`` URI names.

    NAME is looked up in ``[package_dirs]`` of the description (relative to it), then in
    ``ROS_PACKAGE_PATH``, then as a cmeel package installed with pip
    (``<site-packages>/cmeel.prefix/share/NAME``, e.g. ``example-robot-data``).

    Raises:
        RobotError: the package is found nowhere (the message says where it looked and the fix).
    """
    name, _, rest = uri[len(PACKAGE) :].partition("/")
    roots = [toml.parent / package_dirs[name]] if name in package_dirs else []
    roots += [Path(p) / name for p in os.environ.get("ROS_PACKAGE_PATH", "").split(os.pathsep) if p]
    roots += [Path(p) / "cmeel.prefix" / "share" / name for p in _site_packages()]
    for root in roots:
        if root.is_dir():
            return (root / rest).resolve()
    raise RobotError(
        f"{toml}: package {name!r} of {uri} not found (looked in [package_dirs], ROS_PACKAGE_PATH and "
        f'pip\'s cmeel packages); install it or add [package_dirs] {name} = "/path/to/{name}"'
    )


def _site_packages() -> list[str]:
    paths = {sysconfig.get_paths()["purelib"], sysconfig.get_paths()["platlib"]}
    return sorted(paths | {p for p in sys.path if p.endswith("site-packages")})


def compile_model(
    toml: Path,
    source: str,
    keep: Sequence[str],
    home: Mapping[str, float],
    base: Mapping[str, object],
    sites: Mapping[str, Mapping[str, object]],
    exclude: Sequence[Sequence[str]],
    package_dirs: Mapping[str, str],
) -> ModelFile:
    """Compile the model file ``source`` (relative to ``toml``, or ``package://``) for hlik.

    Args:
        toml: The robot description naming the model (for paths and messages).
        source: The ``model`` key: a path or ``package://`` URI of an ``.xml`` (MJCF) or ``.urdf``.
        keep: The joints the robot solves (arms and extra joints); every other joint is welded.
        home: Joint name -> angle (rad); welded joints are welded at it (0 if absent).
        base: ``[base]``: ``pos`` (3,) in m and ``rpy`` (3,) in rad (fixed-axis x, y, z as in URDF).
        sites: ``[sites]``: site name -> ``{body, pos = [x, y, z], rpy = [r, p, y]}`` in the body frame.
        exclude: ``[collision] exclude``: pairs of body names never checked against each other.
        package_dirs: ``[package_dirs]``: package name -> folder (relative to ``toml``).

    Raises:
        RobotError: a missing file or mesh, an unknown body or joint, a site the model already has,
            a malformed entry; each names the file and the part of it.
    """
    path = (
        resolve_package(source, toml, package_dirs) if source.startswith(PACKAGE) else (toml.parent / source)
    )
    path = path.resolve()
    if not path.is_file():
        raise RobotError(f"{toml}: model {source!r} not found ({path})")
    if path.suffix.lower() == ".urdf":
        spec, velocity = _urdf_spec(path, toml, package_dirs)
    else:
        try:
            spec = mujoco.MjSpec.from_file(str(path))
        except ValueError as e:
            raise RobotError(f"{path}: cannot load MJCF: {' '.join(str(e).split())}") from None
        velocity = {}
    model = _compile(spec, path)
    names = {model.joint(i).name for i in range(model.njnt)}
    unknown = [j for j in keep if j not in names]
    if unknown:
        raise RobotError(f"{toml}: joints not in the model {path.name}: {', '.join(unknown)}")
    _place_base(spec, model, toml, base)
    welded = _weld(spec, model, toml, set(keep), home)
    _add_sites(spec, toml, sites)
    for geom in spec.geoms:
        geom.group = COLLISION_GROUP if geom.contype or geom.conaffinity else VISUAL_GROUP
    for pair in exclude:
        if not (isinstance(pair, list | tuple) and len(pair) == 2 and all(isinstance(b, str) for b in pair)):
            raise RobotError(f"{toml}: [collision] exclude entries must be [body, body] pairs, got {pair!r}")
        for body in pair:
            if spec.body(body) is None:
                raise RobotError(f"{toml}: [collision] exclude names body {body!r}, not in {path.name}")
        spec.add_exclude(bodyname1=pair[0], bodyname2=pair[1])
    model = _compile(spec, path)
    touching = _touching_at_home(model, [home.get(model.joint(i).name, 0.0) for i in range(model.njnt)])
    for b1, b2 in touching:
        spec.add_exclude(bodyname1=b1, bodyname2=b2)
    if touching:
        model = _compile(spec, path)
    return ModelFile(path, model, welded, velocity)


def _compile(spec: mujoco.MjSpec, path: Path) -> mujoco.MjModel:
    try:
        return spec.compile()
    except ValueError as e:
        raise RobotError(f"{path}: cannot compile: {' '.join(str(e).split())}") from None


def _urdf_spec(
    path: Path, toml: Path, package_dirs: Mapping[str, str]
) -> tuple[mujoco.MjSpec, dict[str, float]]:
    """An MjSpec of a URDF, keeping its visual geometry, with its mesh paths resolved."""
    try:
        root = ET.parse(path).getroot()
    except (ET.ParseError, OSError) as e:
        raise RobotError(f"{path}: cannot read URDF: {e}") from None
    # MuJoCo's URDF reader drops visuals and the folders of mesh paths unless told otherwise
    mujoco_el = root.find("mujoco")
    if mujoco_el is None:
        mujoco_el = ET.SubElement(root, "mujoco")
    compiler = mujoco_el.find("compiler")
    if compiler is None:
        compiler = ET.SubElement(mujoco_el, "compiler")
    compiler.attrib.update(discardvisual="false", strippath="false", fusestatic="false")
    velocity = {}
    for joint in root.iter("joint"):
        limit = joint.find("limit")
        if limit is not None and "velocity" in limit.attrib:
            velocity[joint.get("name", "")] = float(limit.get("velocity", "nan"))
    try:
        spec = mujoco.MjSpec.from_string(ET.tostring(root, encoding="unicode"))
    except ValueError as e:
        raise RobotError(f"{path}: cannot load URDF: {' '.join(str(e).split())}") from None
    for mesh in spec.meshes:
        file = mesh.file
        resolved = (
            resolve_package(file, toml, package_dirs) if file.startswith(PACKAGE) else path.parent / file
        )
        if not resolved.is_file():
            raise RobotError(f"{path}: mesh {file!r} not found ({resolved})")
        mesh.file = str(resolved)
    return spec, velocity


def _vector(toml: Path, value: object, where: str, default: Sequence[float]) -> np.ndarray:
    value = default if value is None else value
    if not (isinstance(value, list | tuple) and len(value) == 3) or not all(
        isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v) for v in value
    ):
        raise RobotError(f"{toml}: {where} must be three finite numbers, got {value!r}")
    return np.asarray(value, dtype=float)


def _wxyz(rpy: np.ndarray) -> np.ndarray:
    return np.roll(Rotation.from_euler("xyz", rpy).as_quat(), 1)


def _place_base(spec: mujoco.MjSpec, model: mujoco.MjModel, toml: Path, base: Mapping[str, object]) -> None:
    """Put the bodies on the world body at ``[base]``; free joints of a floating base go."""
    pos = _vector(toml, base.get("pos"), "[base] pos", (0, 0, 0))
    rot = Rotation.from_euler("xyz", _vector(toml, base.get("rpy"), "[base] rpy", (0, 0, 0)))
    for body in spec.worldbody.bodies:
        for joint in list(body.joints):
            if joint.type == mujoco.mjtJoint.mjJNT_FREE:
                spec.delete(joint)
        if not base:
            continue
        i = body.id
        body_rot = Rotation.from_quat(np.roll(model.body_quat[i], -1))
        body.pos = pos + rot.apply(model.body_pos[i])
        body.quat = np.roll((rot * body_rot).as_quat(), 1)
        body.alt.type = mujoco.mjtOrientation.mjORIENTATION_QUAT


def _weld(
    spec: mujoco.MjSpec, model: mujoco.MjModel, toml: Path, keep: set[str], home: Mapping[str, float]
) -> dict[str, float]:
    """Delete the joints not kept, turning each body by its joint's home angle. Returns the angles."""
    welded = {}
    for joint in list(spec.joints):
        if joint.name in keep or joint.type == mujoco.mjtJoint.mjJNT_FREE:
            continue
        angle = float(home.get(joint.name, 0.0))
        if angle and joint.type not in (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE):
            raise RobotError(
                f"{toml}: [home] {joint.name}: only hinge and slide joints weld at a non-zero angle"
            )
        if angle:
            j = model.joint(joint.name).id
            b = int(model.jnt_bodyid[j])
            body = spec.body(model.body(b).name)
            body_rot = Rotation.from_quat(np.roll(model.body_quat[b], -1))
            axis, anchor = model.jnt_axis[j], model.jnt_pos[j]
            if joint.type == mujoco.mjtJoint.mjJNT_SLIDE:
                body.pos = model.body_pos[b] + body_rot.apply(axis * angle)
            else:  # a turn about the joint's axis through its anchor, both in the body's frame
                turn = Rotation.from_rotvec(axis * angle)
                body.pos = model.body_pos[b] + body_rot.apply(anchor - turn.apply(anchor))
                body.quat = np.roll((body_rot * turn).as_quat(), 1)
                body.alt.type = mujoco.mjtOrientation.mjORIENTATION_QUAT
        welded[joint.name] = angle
        spec.delete(joint)
    return welded


def _add_sites(spec: mujoco.MjSpec, toml: Path, sites: Mapping[str, Mapping[str, object]]) -> None:
    for name, entry in sites.items():
        where = f"[sites] {name}"
        if not isinstance(entry, Mapping) or not isinstance(entry.get("body"), str):
            raise RobotError(f'{toml}: {where} must be a table {{ body = "...", pos = [x, y, z] }}')
        extra = sorted(set(entry) - {"body", "pos", "rpy"})
        if extra:
            raise RobotError(f"{toml}: {where}: unknown key {extra[0]!r}; choose from: body, pos, rpy")
        if spec.site(name) is not None:
            raise RobotError(f"{toml}: {where}: the model already has a site {name}; leave it out of [sites]")
        body = spec.body(str(entry["body"]))
        if body is None:
            raise RobotError(f"{toml}: {where}: no body {entry['body']!r} in the model")
        pos = _vector(toml, entry.get("pos"), f"{where} pos", (0, 0, 0))
        rpy = _vector(toml, entry.get("rpy"), f"{where} rpy", (0, 0, 0))
        body.add_site(name=name, pos=pos, quat=_wxyz(rpy))


def _touching_at_home(model: mujoco.MjModel, home: Sequence[float]) -> list[tuple[str, str]]:
    """Body pairs whose collision geoms touch at the home configuration."""
    data = mujoco.MjData(model)
    data.qpos[:] = np.asarray(home, dtype=float)[: model.nq] if model.nq else data.qpos
    mujoco.mj_kinematics(model, data)
    mujoco.mj_collision(model, data)
    pairs = set()
    for contact in data.contact[: data.ncon]:
        b1, b2 = sorted(model.body(model.geom_bodyid[g]).name for g in contact.geom)
        pairs.add((b1, b2))
    return sorted(pairs)
