"""Recorded human motion on the MMM model: the first stage of hlik's data flow.

A :class:`HumanMotion` holds what an MMM file records about the subject (joint angles by name,
root pose, markers, height) and the objects of the scene, in SI units on one time base. Marker
positions and object poses are NaN where the recording does not have them (a marker hidden from the
cameras, an object stream that ends early); the subject's joints and root pose are always known.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from scipy.interpolate import CubicSpline, make_interp_spline
from scipy.spatial.transform import Rotation, RotationSpline, Slerp

from hlik.human.limits import MAX_FRAMES as MAX_FRAMES  # re-exported: the readers check them
from hlik.human.limits import RATE_RANGE as RATE_RANGE
from hlik.util.errors import SettingsError, UnknownNameError

WALKING = 0.5  # m the root travels horizontally before a take counts as walking

# The 14 MMM arm joints every motion must carry (kinematics.md §1.2), proximal -> distal, in the
# order of the paper's Table I (s_x, s_y, s_z, e_x, e_z, w_x, w_z=w_y).
ARM_JOINTS: dict[str, tuple[str, ...]] = {
    side: tuple(f"{p}{j}_joint" for j in ("Sx", "Sy", "Sz", "Ex", "Ez", "Wx", "Wy"))
    for side, p in (("left", "L"), ("right", "R"))
}

# The MMM model's ranges of those joints, rad (kinematics.md §1.2; robots/mjcf/mmm.xml has the same).
ARM_RANGES: dict[str, tuple[float, float]] = {
    **{
        f"{p}{j}_joint": r
        for p in "LR"
        for j, r in (
            ("Sx", (-1.22173, 3.31613)),
            ("Ex", (0.0, 2.79253)),
            ("Ez", (-1.5708, 1.5708)),
            ("Wx", (-0.523599, 0.349066)),
        )
    },
    "LSz_joint": (-1.22173, 1.0472),
    "RSz_joint": (-1.0472, 1.22173),
    "LSy_joint": (0.0, 2.79253),
    "RSy_joint": (-2.79253, 0.0),
    "LWy_joint": (-1.22173, 1.5708),
    "RWy_joint": (-1.5708, 1.22173),
}


_MIRROR = np.diag([-1.0, 1.0, 1.0])  # reflection through the sagittal plane (x = right)


def frame_period(times: np.ndarray) -> float:
    """The median step of a time base (T,), s; 0.01 (100 Hz, the paper's rate) for a single frame."""
    return float(np.median(np.diff(times))) if len(times) > 1 else 0.01


@dataclass(frozen=True, eq=False)
class ObjectMotion:
    """Pose of a scene object on the motion's time base.

    Attributes:
        name: Object name as recorded.
        position: (T, 3) origin position in the world, metres; NaN where the pose was not recorded.
        rotation: (T, 3, 3) orientation in the world; NaN where the pose was not recorded.
        markers: Marker name -> (T, 3) positions in metres; NaN where the marker was not seen.
    """

    name: str
    position: np.ndarray
    rotation: np.ndarray
    markers: Mapping[str, np.ndarray] = field(default_factory=dict)


@dataclass(frozen=True, eq=False)
class HumanMotion:
    """A human motion on the MMM reference model.

    Attributes:
        name: Motion name (the file's stem by default).
        times: (T,) strictly increasing timestamps in seconds.
        joint_names: The J recorded joint names (MMM names, e.g. ``LSx_joint``).
        joints: (T, J) joint angles in radians; columns follow ``joint_names``.
        root_position: (T, 3) root (hip-level) position in the world, metres.
        root_rotation: (T, 3, 3) root orientation in the world.
        height: Subject height in metres (the MMM model is scaled to it).
        mass: Subject mass in kg, if recorded.
        markers: Marker name -> (T, 3) positions in metres; NaN where the marker was not seen.
        objects: Object name -> :class:`ObjectMotion`.
        source: File the motion was read from, if any.
        notes: One-line warnings about the recording found while reading it (each names the file,
            the motion and sensor, the span and the problem); kept through crop and resample.
    """

    name: str
    times: np.ndarray
    joint_names: tuple[str, ...]
    joints: np.ndarray
    root_position: np.ndarray
    root_rotation: np.ndarray
    height: float
    mass: float | None = None
    markers: Mapping[str, np.ndarray] = field(default_factory=dict)
    objects: Mapping[str, ObjectMotion] = field(default_factory=dict)
    source: Path | None = None
    notes: tuple[str, ...] = ()

    @property
    def n_frames(self) -> int:
        return len(self.times)

    @property
    def duration(self) -> float:
        return float(self.times[-1] - self.times[0])

    @property
    def rate(self) -> float:
        """Median frame rate in Hz (:func:`frame_period`)."""
        return 1.0 / frame_period(self.times)

    def walking(self) -> str:
        """A note if the subject walks: its root (hips) travels more than :data:`WALKING`
        horizontally from where it starts (any format: an MMM take's root, a fitted one's through
        the shoulders); else ``""``. A robot standing in one place cannot follow."""
        travel = float(np.max(np.linalg.norm(self.root_position[:, :2] - self.root_position[0, :2], axis=-1)))
        if travel <= WALKING:
            return ""
        where = f"{self.source}: " if self.source else ""
        return (
            f"{where}motion: the subject walks ({travel:.1f} m from where it starts); a robot standing "
            "in one place cannot follow, so expect hands far off their targets (crop the take to where "
            "it stands: --span)"
        )

    def joint(self, name: str) -> np.ndarray:
        """(T,) angles of one joint, by name."""
        try:
            return self.joints[:, self.joint_names.index(name)]
        except ValueError:
            raise UnknownNameError(f"{self.name}: no joint {name!r}") from None

    def angles(self, names: Sequence[str]) -> np.ndarray:
        """(T, k) angles of the named joints, in the order given."""
        return np.stack([self.joint(n) for n in names], axis=1)

    def scaled(
        self, factor: float, why: str = "", about: np.ndarray | None = None, to: np.ndarray | None = None
    ) -> HumanMotion:
        """The same motion by a subject ``factor`` times as tall: the height, root, markers and object
        positions scale about the world point ``about`` (3,), m, which moves to ``to`` (3,); both
        default to the origin, so the floor at z = 0 stays. The joint angles stay. ``why`` goes into
        a note.

        Raises:
            hlik.util.errors.SettingsError: ``factor`` is not a positive finite number.
        """
        if not (math.isfinite(factor) and factor > 0):
            where = self.source or self.name
            raise SettingsError(f"{where}: subject scale must be positive, got {factor:g}")
        c = np.zeros(3) if about is None else np.asarray(about, dtype=float)
        d = c if to is None else np.asarray(to, dtype=float)
        if factor == 1.0 and np.array_equal(c, d):
            return self

        def move(p: np.ndarray) -> np.ndarray:
            return d + factor * (p - c)

        note = (
            f"{self.source or self.name}: subject scaled by {factor:.3f} "
            f"({self.height:.2f} m -> {factor * self.height:.2f} m){why}"
        )
        return replace(
            self,
            height=self.height * factor,
            root_position=move(self.root_position),
            markers={k: move(v) for k, v in self.markers.items()},
            objects={
                k: replace(o, position=move(o.position), markers={m: move(v) for m, v in o.markers.items()})
                for k, o in self.objects.items()
            },
            notes=(*self.notes, note),
        )

    def crop(self, start: float, stop: float) -> HumanMotion:
        """The frames with ``start <= t - t0 <= stop`` (seconds from the first frame)."""
        t = self.times - self.times[0]
        keep = (t >= start - 1e-9) & (t <= stop + 1e-9)
        return self.frames(keep)

    def retimed(self, factor: float) -> HumanMotion:
        """The same motion played ``factor`` times as long (2: at half the speed), resampled to
        its own rate: time scaling, so that a robot follows a motion too fast for its limits.

        Raises:
            hlik.util.errors.SettingsError: the result would have too many frames (:meth:`resample`).
        """
        if factor == 1.0:
            return self
        rate, t0 = self.rate, self.times[0]
        slow = replace(self, times=t0 + (self.times - t0) * factor)
        return slow.resample(rate) if self.n_frames > 1 else slow

    def resample(self, rate: float) -> HumanMotion:
        """Resample to ``rate`` Hz: quintic splines (C⁴) for angles and positions, rotation splines
        (C²) for rotations. Markers and object poses are splined over each stretch they were seen in
        and stay NaN in between.

        Raises:
            hlik.util.errors.SettingsError: ``rate`` is not a finite rate within :data:`RATE_RANGE`, or the
                result would have more than :data:`MAX_FRAMES` frames.
        """
        where = self.source or self.name
        low, high = RATE_RANGE
        if not (math.isfinite(rate) and low <= rate <= high):
            raise SettingsError(
                f"{where}: resampling rate must be between {low:g} and {high:g} Hz, got {rate:g}"
            )
        n = math.floor(self.duration * rate + 1e-6) + 1
        if n > MAX_FRAMES:
            raise SettingsError(
                f"{where}: resampling {self.times[0]:g}-{self.times[-1]:g} s ({self.duration:g} s) at "
                f"{rate:g} Hz would make {n} frames, more than {MAX_FRAMES}; crop the motion or lower "
                "the rate"
            )
        t_new = self.times[0] + np.arange(0.0, self.duration + 1e-9, 1.0 / rate)
        return replace(
            self,
            times=t_new,
            joints=_spline(self.times, self.joints, t_new),
            root_position=_spline(self.times, self.root_position, t_new),
            root_rotation=_rotation_spline(self.times, self.root_rotation, t_new),
            markers={k: _spline(self.times, v, t_new) for k, v in self.markers.items()},
            objects={
                k: replace(
                    o,
                    position=_spline(self.times, o.position, t_new),
                    rotation=_rotation_spline(self.times, o.rotation, t_new),
                    markers={m: _spline(self.times, v, t_new) for m, v in o.markers.items()},
                )
                for k, o in self.objects.items()
            },
        )

    def mirrored(self) -> HumanMotion:
        """The left-right mirror image (reflection x -> -x of the whole scene).

        Left and right joints, markers and objects swap; a joint about the x axis keeps its angle,
        one about y or z changes sign, because a reflection reverses the sense of rotation about
        axes lying in the mirror plane.
        """
        names = self.joint_names
        src = [names.index(_swap_side(n)) if _swap_side(n) in names else i for i, n in enumerate(names)]
        sign = np.array([_mirror_sign(n) for n in names])
        markers = _mirror_points(self.markers)
        objects = {
            k: replace(
                o,
                position=o.position @ _MIRROR,
                rotation=_MIRROR @ o.rotation @ _MIRROR,
                markers=_mirror_points(o.markers),
            )
            for k, o in self.objects.items()
        }
        return replace(
            self,
            name=f"{self.name}_mirrored",
            joints=self.joints[:, src] * sign,
            root_position=self.root_position @ _MIRROR,
            root_rotation=_MIRROR @ self.root_rotation @ _MIRROR,
            markers=markers,
            objects=objects,
        )

    def frames(self, keep: np.ndarray | slice) -> HumanMotion:
        """The frames ``keep`` selects: a (T,) boolean mask, integer indices (in any order, with
        repeats) or a slice; every stream, objects and markers included (a slice gives views)."""
        return replace(
            self,
            times=self.times[keep],
            joints=self.joints[keep],
            root_position=self.root_position[keep],
            root_rotation=self.root_rotation[keep],
            markers={k: v[keep] for k, v in self.markers.items()},
            objects={
                k: replace(
                    o,
                    position=o.position[keep],
                    rotation=o.rotation[keep],
                    markers={m: v[keep] for m, v in o.markers.items()},
                )
                for k, o in self.objects.items()
            },
        )


def _spline(t: np.ndarray, y: np.ndarray, t_new: np.ndarray) -> np.ndarray:
    """Values (T_new, ...) at ``t_new`` of quintic splines through ``y`` (T, ...), one per stretch of
    frames where ``y`` is finite; NaN outside those stretches (a spline across a gap would invent
    values the recording does not have).

    Quintic, not cubic: a cubic's jerk is constant between knots and jumps at each, so from 10 Hz
    data the mapped pose and the hand targets jerk in steps every 10th frame at 100 Hz, which MJE
    (a third difference) scores as a 0-1 barcode; a quintic's jerk is continuous."""
    return _by_stretch(t, y, t_new, _quintic)


def _rotation_spline(t: np.ndarray, rot: np.ndarray, t_new: np.ndarray) -> np.ndarray:
    """Rotations (T_new, 3, 3) at ``t_new`` on a C² spline through ``rot`` (T, 3, 3). Slerp would
    kink the angular velocity at every recorded frame, and with the root's every hand target: a
    jerk spike each 10th frame at 100 Hz from 10 Hz data, which the tracking solvers reproduce and
    MJE scores. NaN between stretches, as :func:`_spline`."""
    return _by_stretch(t, rot, t_new, _rotations)


def _quintic(t: np.ndarray, y: np.ndarray, t_new: np.ndarray) -> np.ndarray:
    """A quintic spline (not-a-knot) from 6 knots on, a cubic from 4, linear below."""
    if len(t) < 4:  # a spline needs 4 knots; fall back to linear on very short stretches
        flat = y.reshape(len(t), -1)
        return np.stack([np.interp(t_new, t, c) for c in flat.T], -1).reshape((len(t_new), *y.shape[1:]))
    if len(t) >= 6:
        return make_interp_spline(t, y, k=5, axis=0)(t_new)
    return CubicSpline(t, y, axis=0)(t_new)


def _rotations(t: np.ndarray, rot: np.ndarray, t_new: np.ndarray) -> np.ndarray:
    return RotationSpline(t, Rotation.from_matrix(rot))(np.clip(t_new, t[0], t[-1])).as_matrix()


def stretches(mask: np.typing.ArrayLike) -> list[tuple[int, int]]:
    """The runs ``[a, b)`` of consecutive True frames of ``mask`` (T,), in order."""
    edges = np.diff(np.concatenate([[0], np.asarray(mask).astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1).tolist(), np.flatnonzero(edges == -1).tolist()))


def _by_stretch(
    t: np.ndarray,
    y: np.ndarray,
    t_new: np.ndarray,
    fit: Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray],
) -> np.ndarray:
    known = np.all(np.isfinite(y.reshape(len(t), -1)), axis=1)
    if known.all():
        return fit(t, y, t_new)
    out = np.full((len(t_new), *y.shape[1:]), np.nan)
    for a, b in stretches(known):
        inside = (t_new >= t[a]) & (t_new <= t[b - 1])
        if not inside.any():
            continue
        if b - a == 1:
            out[inside] = y[a]
        else:
            out[inside] = fit(t[a:b], y[a:b], t_new[inside])
    return out


def _slerp(t: np.ndarray, rot: np.ndarray, t_new: np.ndarray) -> np.ndarray:
    return Slerp(t, Rotation.from_matrix(rot))(np.clip(t_new, t[0], t[-1])).as_matrix()


def _swap_side(name: str) -> str:
    if name.startswith("Left"):
        return "Right" + name[4:]
    if name.startswith("Right"):
        return "Left" + name[5:]
    if len(name) > 1 and name[0] in "LR" and name[1].isupper():
        return {"L": "R", "R": "L"}[name[0]] + name[1:]
    return name


def _mirror_sign(joint_name: str) -> float:
    axis = joint_name.removesuffix("_joint")[-1:]
    return -1.0 if axis in ("y", "z") else 1.0


def _mirror_points(points: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    out = {}
    for name, p in points.items():
        other = _swap_side(name)
        out[other if other in points else name] = p @ _MIRROR
    return out
