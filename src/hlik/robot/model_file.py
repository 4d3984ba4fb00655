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
  pairs that touch at the home pose (links that overlap by construction), and those closer than
  1 cm at home and in every one of 64 random configurations (parts of one joint), are excluded
  from collision, with the pairs of ``[collision] exclude``.
- a body with visual geometry but no collision geometry (the G1's rubber hands, pelvis and waist
  links have visual meshes only) gets a fitted collision primitive per visual geom
  (:func:`fit_collision_shapes`), so that it is seen by the self-collision checks.
"""

from __future__ import annotations

import math
import os
import sys
import sysconfig
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np
from scipy.spatial.transform import Rotation

from hlik.util.errors import RobotError
from hlik.util.spatial import wxyz_from_rpy

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
        effort: Joint name -> torque limit (N m) a URDF gives (``<limit effort>``); empty for MJCF.
    """

    path: Path
    model: mujoco.MjModel
    welded: Mapping[str, float]
    velocity: Mapping[str, float]
    effort: Mapping[str, float] = field(default_factory=dict)


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
    spec, limits, model = _load(toml, path, package_dirs)
    names = {model.joint(i).name for i in range(model.njnt)}
    unknown = [j for j in keep if j not in names]
    if unknown:
        raise RobotError(f"{toml}: joints not in the model {path.name}: {', '.join(unknown)}")
    _place_base(spec, model, toml, base)
    _couplings(spec, toml, set(keep))
    welded = _weld(spec, model, toml, set(keep), home)
    _add_sites(spec, toml, sites)
    fit_collision_shapes(spec, model)
    for geom in spec.geoms:
        geom.group = COLLISION_GROUP if geom.contype or geom.conaffinity else VISUAL_GROUP
    _add_excludes(spec, toml, path, exclude)
    model = _compile(spec, path)
    at_home = [home.get(model.joint(i).name, 0.0) for i in range(model.njnt)]
    touching = sorted({*_touching_at_home(model, at_home), *_near_by_construction(model, at_home)})
    for b1, b2 in touching:
        spec.add_exclude(bodyname1=b1, bodyname2=b2)
    if touching:
        model = _compile(spec, path)
    return ModelFile(path, model, welded, limits["velocity"], limits["effort"])


def _load(
    toml: Path, path: Path, package_dirs: Mapping[str, str]
) -> tuple[mujoco.MjSpec, dict[str, dict[str, float]], mujoco.MjModel]:
    """The spec of the model file ``path`` (MJCF or URDF), its URDF limits and its compiled model;
    the model's own faults name the robot file ``toml`` too: the file a user wrote and can fix."""
    try:
        if path.suffix.lower() == ".urdf":
            spec, limits = _urdf_spec(path, toml, package_dirs)
        else:
            try:
                spec = mujoco.MjSpec.from_file(str(path))
            except ValueError as e:
                raise RobotError(f"{path}: cannot load MJCF: {' '.join(str(e).split())}") from None
            limits = {"velocity": {}, "effort": {}}
        model = _compile(spec, path)
    except RobotError as e:
        said = str(e)
        raise RobotError(f"{toml}: model {said}" if said.startswith(str(path)) else said) from None
    return spec, limits, model


def _add_excludes(spec: mujoco.MjSpec, toml: Path, path: Path, exclude: Sequence[Sequence[str]]) -> None:
    """The ``[collision] exclude`` pairs of ``toml`` added to ``spec`` (of the model ``path``)."""
    for pair in exclude:
        if not (isinstance(pair, list | tuple) and len(pair) == 2 and all(isinstance(b, str) for b in pair)):
            raise RobotError(f"{toml}: [collision] exclude entries must be [body, body] pairs, got {pair!r}")
        for body in pair:
            if spec.body(body) is None:
                raise RobotError(f"{toml}: [collision] exclude names body {body!r}, not in {path.name}")
        spec.add_exclude(bodyname1=pair[0], bodyname2=pair[1])


def _compile(spec: mujoco.MjSpec, path: Path) -> mujoco.MjModel:
    try:
        return spec.compile()
    except ValueError as e:
        raise RobotError(f"{path}: cannot compile: {' '.join(str(e).split())}") from None


def _urdf_spec(
    path: Path, toml: Path, package_dirs: Mapping[str, str]
) -> tuple[mujoco.MjSpec, dict[str, dict[str, float]]]:
    """An MjSpec of a URDF, keeping its visual geometry, with its mesh paths resolved, and the
    joints' ``<limit velocity>`` (rad/s) and ``<limit effort>`` (N m) by attribute and joint name."""
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
    limits: dict[str, dict[str, float]] = {"velocity": {}, "effort": {}}
    for joint in root.iter("joint"):
        limit = joint.find("limit")
        for key, table in limits.items():
            if limit is not None and key in limit.attrib:
                table[joint.get("name", "")] = float(limit.get(key, "nan"))
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
    return spec, limits


def _vector(toml: Path, value: object, where: str, default: Sequence[float]) -> np.ndarray:
    value = default if value is None else value
    if not (isinstance(value, list | tuple) and len(value) == 3) or not all(
        isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v) for v in value
    ):
        raise RobotError(f"{toml}: {where} must be three finite numbers, got {value!r}")
    return np.asarray(value, dtype=float)


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


def _couplings(spec: mujoco.MjSpec, toml: Path, keep: set[str]) -> None:
    """Joint couplings (an MJCF ``<equality><joint>``, what MuJoCo makes of a URDF ``<mimic>``):
    hlik's solvers move every joint on its own, so a coupling between two joints they solve, or
    between one they solve and one they weld, is refused naming both; one between welded joints
    goes with them (each held at its home angle).

    Raises:
        RobotError: a coupling that involves a solved joint.
    """
    for eq in list(spec.equalities):
        if eq.type != mujoco.mjtEq.mjEQ_JOINT:
            continue
        joints = [n for n in (eq.name1, eq.name2) if n]
        solved = [n for n in joints if n in keep]
        if solved:
            pair = " and ".join(joints) if len(joints) == 2 else f"{joints[0]} (fixed)"
            raise RobotError(
                f"{toml}: joints {pair} are coupled in the model (a URDF <mimic> or a joint equality), "
                f"and hlik solves {', '.join(solved)}: its solvers move joints independently; leave "
                "them out of [arms] and extra_joints (welded at [home]) or remove the coupling"
            )
        spec.delete(eq)


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
        body.add_site(name=name, pos=pos, quat=wxyz_from_rpy(rpy))


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


NEAR = 0.01  # m: body pairs always this close are parts of one joint, not a collision to avoid
SAMPLES = 64  # random configurations :func:`_near_by_construction` tries


def _near_by_construction(model: mujoco.MjModel, home: Sequence[float]) -> list[tuple[str, str]]:
    """Body pairs whose collision geoms are closer than :data:`NEAR` at home and in every one of
    :data:`SAMPLES` random configurations within the joint limits (seeded): parts that sit against
    each other at a joint whatever the joints do, such as the G1's shoulder links against the
    convex hull of its torso mesh, 8 mm apart. A solver keeping a 1 cm margin would push at them in
    every frame, against the targets; MoveIt's setup assistant disables such "always" pairs too."""
    margin = model.geom_margin.copy()
    model.geom_margin[:] = NEAR  # mj_collision then reports every pair closer than that
    try:
        data = mujoco.MjData(model)
        rng = np.random.default_rng(0)
        lo = np.where(model.jnt_limited.astype(bool), model.jnt_range[:, 0], -np.pi)[: model.nq]
        hi = np.where(model.jnt_limited.astype(bool), model.jnt_range[:, 1], np.pi)[: model.nq]
        near: set[tuple[str, str]] | None = None
        for k in range(SAMPLES + 1):
            q = np.asarray(home, dtype=float)[: model.nq] if k == 0 else rng.uniform(lo, hi)
            data.qpos[:] = q if model.nq else data.qpos
            mujoco.mj_kinematics(model, data)
            mujoco.mj_collision(model, data)
            found = {
                tuple(sorted(model.body(model.geom_bodyid[g]).name for g in c.geom))
                for c in data.contact[: data.ncon]
            }
            near = found if near is None else near & found
            if not near:
                break
        return sorted(near or ())
    finally:
        model.geom_margin[:] = margin


FITTED = "col_fitted_"  # name prefix of the collision primitives fitted to visual-only bodies
_UNBOUNDED = (mujoco.mjtGeom.mjGEOM_PLANE, mujoco.mjtGeom.mjGEOM_HFIELD)


def fit_collision_shapes(spec: mujoco.MjSpec, model: mujoco.MjModel) -> list[str]:
    """Add a collision primitive for each visual geom of every body that has visual geometry but no
    collision geometry (``model`` is ``spec`` compiled). A primitive visual geom is copied; a mesh
    gets the smaller (by volume) of a box and a capsule covering all its vertices, both in the
    mesh's frame (MuJoCo's, the principal axes of its inertia): the box is the vertices' bounding
    box there, the capsule runs along the box's longest axis, its radius the vertices' largest
    distance from that axis and its ends just far enough to cover the rest. Mass-less (density
    0), with the contype/conaffinity most of the model's collision geoms have (1/1 if none).

    Returns:
        The names of the bodies that got one.
    """
    colliding = (model.geom_contype | model.geom_conaffinity) > 0
    kinds = list(zip(model.geom_contype[colliding].tolist(), model.geom_conaffinity[colliding].tolist()))
    contype, conaffinity = max(set(kinds), key=kinds.count) if kinds else (1, 1)
    # the spec's bodies in the compiled order (their ids are gone once the spec is edited)
    listed = list(spec.bodies)
    bodies = dict(enumerate(listed)) if len(listed) == model.nbody else {}
    bodies.update({i: spec.body(model.body(i).name) for i in range(1, model.nbody) if model.body(i).name})
    taken = {geom.name for geom in spec.geoms}
    fitted = []
    for b in range(1, model.nbody):
        own = np.flatnonzero(model.geom_bodyid == b)
        geoms = [int(g) for g in own if model.geom_type[g] not in _UNBOUNDED]
        if not geoms or colliding[own].any() or b not in bodies:
            continue
        stem = FITTED + (model.body(b).name or f"body{b}")
        for k, g in enumerate(geoms):
            kind, size, pos, quat = _fitted_primitive(model, g)
            name = stem if len(geoms) == 1 else f"{stem}_{k}"
            while name in taken:
                name += "_"
            taken.add(name)
            geom = bodies[b].add_geom(name=name, type=kind, size=size, pos=pos, quat=quat, density=0.0)
            geom.contype, geom.conaffinity, geom.group = contype, conaffinity, COLLISION_GROUP
        fitted.append(model.body(b).name)
    return fitted


def _fitted_primitive(model: mujoco.MjModel, g: int) -> tuple[int, np.ndarray, np.ndarray, np.ndarray]:
    """Type, size, position and quaternion (wxyz) in the body frame of the primitive covering geom g."""
    pos, quat = np.array(model.geom_pos[g]), np.array(model.geom_quat[g])
    if model.geom_type[g] != mujoco.mjtGeom.mjGEOM_MESH:
        return mujoco.mjtGeom(int(model.geom_type[g])), np.array(model.geom_size[g]), pos, quat
    mesh = int(model.geom_dataid[g])
    start = int(model.mesh_vertadr[mesh])
    vert = np.array(model.mesh_vert[start : start + int(model.mesh_vertnum[mesh])], dtype=float)
    lo, hi = vert.min(axis=0), vert.max(axis=0)
    centre, half = (lo + hi) / 2, np.maximum((hi - lo) / 2, 1e-4)
    box_volume = 8.0 * float(np.prod(half))
    # capsule along the longest axis of the box, through the box's centre
    axis = int(np.argmax(half))
    others = [i for i in range(3) if i != axis]
    radial = np.linalg.norm(vert[:, others] - centre[others], axis=1)
    radius = max(float(radial.max()), 1e-4)
    reach = np.sqrt(np.maximum(radius**2 - radial**2, 0.0))
    t = vert[:, axis]
    low_end, high_end = float(np.min(t + reach)), float(np.max(t - reach))
    half_length = max((high_end - low_end) / 2, 0.0)
    capsule_volume = np.pi * radius**2 * 2 * half_length + 4 / 3 * np.pi * radius**3
    rot = Rotation.from_quat(np.roll(quat, -1))
    if box_volume <= capsule_volume:
        return mujoco.mjtGeom.mjGEOM_BOX, half, pos + rot.apply(centre), quat
    middle = centre.copy()
    middle[axis] = (low_end + high_end) / 2
    # the capsule's z along the chosen axis: a cyclic permutation of the mesh frame's axes
    columns = np.eye(3)[:, [(axis + 1) % 3, (axis + 2) % 3, axis]]
    turn = rot * Rotation.from_matrix(columns)
    size = np.array([radius, max(half_length, 1e-6), 0.0])
    return mujoco.mjtGeom.mjGEOM_CAPSULE, size, pos + rot.apply(middle), np.roll(turn.as_quat(), 1)
