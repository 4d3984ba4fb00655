"""Deriving the MMM -> robot joint mapping with the paper's procedure (Sec. III-A).

1. Common default pose: the MMM model with both elbows flexed 90° (forearms forward, palms facing
   each other); the robot arm is fitted to it (upper-arm and forearm directions, hand frame).
2. Each MMM joint is moved by a small angle; the robot joint whose motion reproduces the same
   segment motion (rotation of upper arm, forearm and hand; velocity of elbow, wrist and TCP,
   per unit arm length) is assigned to it, with the sign of the agreement (Hungarian assignment).
   Robot joints with no counterpart are held (a = 0).
3. The default pose is refined so that assigned joint axes are parallel, "perceptually" rounded
   (angles within 0.1 rad of a multiple of π/4 are snapped to it) and clipped into the joint
   limits, which gives the offsets b = q0 - a * q_mmm0.
4. Dynamic offsets: for every assigned robot joint and every other MMM joint of the same segment
   group (shoulder, elbow, wrist), the MMM joint is swept across its range and the robot joint
   re-fitted alone; a visible, systematic linear drift (gain above 0.05, explaining most of the
   re-fit) becomes an offset on that MMM joint (the paper found one: ARMAR-6's Sho2 on s_x).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
from scipy.optimize import least_squares, linear_sum_assignment, minimize_scalar
from scipy.spatial.transform import Rotation

from hlik.human.kinematics import human_model
from hlik.human.motion import ARM_JOINTS
from hlik.robot.mapping import DynamicOffset, JointMap, JointMapping
from hlik.robot.model import SIDES, Robot
from hlik.util.atomic import atomic_path

SNAP_STEP = np.pi / 4
SNAP_TOL = 0.1
MATCH_THRESHOLD = 0.7
DRIFT_ERROR = 0.25  # rad of pose residual (segment directions and hand frame)
DEFAULT_POSE = {"LEx_joint": np.pi / 2, "REx_joint": np.pi / 2}


@dataclass(frozen=True)
class Calibration:
    """A derived mapping and how well it fits.

    Attributes:
        mapping: The joint mapping.
        score: Robot joint -> agreement |cos| of its assigned MMM joint's motion (0 if held).
        residual: Side -> hand-orientation error of the default pose in rad, after rounding.
    """

    mapping: JointMapping
    score: dict[str, float]
    residual: dict[str, float]


class _Arm:
    """Evaluates one arm of a model: segment directions, TCP frame, site Jacobians."""

    def __init__(self, model: mujoco.MjModel, side: str, qpos0: np.ndarray, joints: tuple[str, ...]):
        self.model, self.data = model, mujoco.MjData(model)
        self.qpos0 = qpos0.copy()
        self.adr = np.array([model.jnt_qposadr[model.joint(j).id] for j in joints])
        self.dof = np.array([model.jnt_dofadr[model.joint(j).id] for j in joints])
        self.sites = [model.site(f"{side}_{s}").id for s in ("shoulder", "elbow", "wrist", "tcp")]

    def set(self, q: np.ndarray) -> None:
        self.data.qpos[:] = self.qpos0
        self.data.qpos[self.adr] = q
        mujoco.mj_kinematics(self.model, self.data)

    def pose(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        self.set(q)
        s, e, w, _ = (self.data.site_xpos[i] for i in self.sites)
        u, f = e - s, w - e
        rot = self.data.site_xmat[self.sites[3]].reshape(3, 3).copy()
        return u / np.linalg.norm(u), f / np.linalg.norm(f), rot

    def length(self) -> float:
        s, e, w, _ = (self.data.site_xpos[i] for i in self.sites)
        return float(np.linalg.norm(e - s) + np.linalg.norm(w - e))

    def axes(self, q: np.ndarray) -> np.ndarray:
        """(k, 3) world joint axes."""
        self.set(q)
        jid = [self.model.dof_jntid[d] for d in self.dof]
        return self.data.xaxis[jid].copy()

    def effects(self, q: np.ndarray) -> np.ndarray:
        """(k, 18) per joint: rotation and velocity/length of elbow, wrist and TCP sites."""
        self.set(q)
        mujoco.mj_comPos(self.model, self.data)
        length, blocks = self.length(), []
        for sid in self.sites[1:]:
            jp, jr = np.zeros((3, self.model.nv)), np.zeros((3, self.model.nv))
            mujoco.mj_jacSite(self.model, self.data, jp, jr, sid)
            blocks += [jr[:, self.dof], jp[:, self.dof] / length]
        return np.concatenate(blocks, axis=0).T


def calibrate(robot: Robot) -> Calibration:
    """Derive ``robot``'s joint mapping from its model (see the module docstring)."""
    human = human_model(1.8)
    h_qpos0 = np.zeros(human.nq)
    h_qpos0[3] = 1.0
    maps, score, residual = [], {}, {}
    for side in SIDES:
        h_names = ARM_JOINTS[side]
        h_arm = _Arm(human, side, h_qpos0, h_names)
        q_h0 = np.array([DEFAULT_POSE.get(n, 0.0) for n in h_names])
        r_names = robot.arm_joints[side]
        r_idx = robot.index(r_names)
        r_arm = _Arm(robot.model, side, robot.home, r_names)
        target = h_arm.pose(q_h0)
        q0, pairs, signs, sim = _default_pose(r_arm, h_arm, q_h0, target, robot.home[r_idx])
        q0 = _round(q0, robot.lower[r_idx], robot.upper[r_idx])
        residual[side] = _orientation_error(r_arm.pose(q0)[2], target[2])
        side_maps = []
        for j, name in enumerate(r_names):
            i = pairs.get(j)
            if i is None:
                side_maps.append(JointMap(name, None, 0.0, float(q0[j])))
                score[name] = 0.0
                continue
            a = float(signs[j])
            side_maps.append(JointMap(name, h_names[i], a, float(q0[j] - a * q_h0[i])))
            score[name] = float(sim[j])
        maps += _dynamic_offsets(side_maps, h_arm, r_arm, q_h0, h_names, human)
    return Calibration(JointMapping(tuple(maps)), score, residual)


def _default_pose(r_arm: _Arm, h_arm: _Arm, q_h0, target, home):
    """Robot default pose and joint assignment.

    Candidates start from every good pose fit and from ``home``; the one matching most MMM joints,
    then with the smallest misfit, wins; exact ties (such as the Panda's parallel joints 5 and 7
    at a straight wrist) resolve towards the robot's authored home pose.
    """
    h_eff, h_axes = h_arm.effects(q_h0), h_arm.axes(q_h0)
    best, best_key = None, None
    for start in _fit_pose(r_arm, target, home) + [home]:
        pairs, signs, sim = _assign(h_eff, r_arm.effects(start))
        q = _refine(r_arm, target, start, pairs, signs, h_axes)
        misfit = _misfit(r_arm, target, q, pairs, signs, h_axes)
        key = (-len(pairs), round(misfit, 3), float(np.sum(np.angle(np.exp(1j * (q - home))) ** 2)))
        if best_key is None or key < best_key:
            best, best_key = (q, pairs, signs, sim), key
    return best


def _misfit(arm: _Arm, target, q, pairs, signs, h_axes) -> float:
    js = sorted(pairs)
    axes = arm.axes(q)
    err = [axes[j] - signs[j] * h_axes[pairs[j]] for j in js]
    return float(np.sum(np.square(err)) + np.sum(_pose_residual(arm, q, target)[6:] ** 2))


def _pose_residual(arm: _Arm, q: np.ndarray, target) -> np.ndarray:
    u, f, rot = arm.pose(q)
    err = Rotation.from_matrix(target[2].T @ rot).as_rotvec()
    return np.concatenate([u - target[0], f - target[1], err])


def _fit_pose(arm: _Arm, target, home: np.ndarray) -> list[np.ndarray]:
    """Local fits of the default pose from several starts (the good ones)."""
    rng = np.random.default_rng(0)
    starts = [home, np.zeros_like(home)] + [home + rng.normal(0, 0.8, home.shape) for _ in range(8)]
    sols = [
        least_squares(lambda q: np.concatenate([_pose_residual(arm, q, target), 1e-3 * (q - home)]), x0)
        for x0 in starts
    ]
    best = min(s.cost for s in sols)
    return [s.x for s in sols if s.cost < best + 1e-2]


def _assign(h_eff: np.ndarray, r_eff: np.ndarray):
    """Robot joint -> MMM joint with the most similar segment motion, and its sign."""
    hn = h_eff / np.linalg.norm(h_eff, axis=1, keepdims=True)
    rn = r_eff / np.linalg.norm(r_eff, axis=1, keepdims=True)
    cos = rn @ hn.T
    rows, cols = linear_sum_assignment(-np.abs(cos))
    pairs, signs, sim = {}, np.zeros(len(r_eff)), np.zeros(len(r_eff))
    for j, i in zip(rows, cols):
        if abs(cos[j, i]) >= MATCH_THRESHOLD:
            pairs[j], signs[j], sim[j] = i, np.sign(cos[j, i]), abs(cos[j, i])
    return pairs, signs, sim


def _refine(arm: _Arm, target, q0, pairs, signs, h_axes) -> np.ndarray:
    """Make assigned axes parallel while keeping the hand frame and segment directions."""
    js = np.array(sorted(pairs))
    if js.size == 0:
        return q0
    want = np.array([signs[j] * h_axes[pairs[j]] for j in js])

    def res(q):
        # Axes and hand frame decide; site directions only break ties (offset links such as the
        # Panda's elbow would otherwise tilt the whole arm to line up the joint centres).
        pose = _pose_residual(arm, q, target)
        return np.concatenate([(arm.axes(q)[js] - want).ravel(), 0.1 * pose[:6], pose[6:], 1e-3 * (q - q0)])

    return least_squares(res, q0).x


def _round(q: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    q = np.arctan2(np.sin(q), np.cos(q))
    for k in range(len(q)):  # prefer the 2π-equivalent inside the limits
        for alt in (q[k] - 2 * np.pi, q[k] + 2 * np.pi):
            if not lower[k] <= q[k] <= upper[k] and lower[k] <= alt <= upper[k]:
                q[k] = alt
    snapped = np.round(q / SNAP_STEP) * SNAP_STEP
    q = np.where(np.abs(q - snapped) < SNAP_TOL, snapped, q)
    return np.clip(q, lower, upper)


def _orientation_error(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.linalg.norm(Rotation.from_matrix(a.T @ b).as_rotvec()))


def _dynamic_offsets(maps, h_arm, r_arm, q_h0, h_names, human) -> list[JointMap]:
    """Attach a linear offset where a robot joint's best value drifts with another MMM joint."""
    ranges = {n: human.jnt_range[human.joint(n).id] for n in h_names}
    out = []
    for j, m in enumerate(maps):
        best = None
        if m.mmm is not None:
            for i, src in enumerate(h_names):
                if src == m.mmm or src[1] != m.mmm[1]:  # same segment group: S, E or W
                    continue
                fit = _sweep(maps, j, i, h_arm, r_arm, q_h0, h_names, ranges[src])
                if fit is not None and (best is None or abs(fit[1]) > abs(best[1])):
                    best = (src, fit[1])
        if best is None:
            out.append(m)
            continue
        # The offset is zero at the default pose: b absorbs gain * q_src(default).
        src, gain = best[0], round(best[1], 4)
        b = m.b - gain * q_h0[h_names.index(src)]
        out.append(JointMap(m.joint, m.mmm, m.a, b, DynamicOffset(src, gain)))
    return out


def _sweep(maps, j, i, h_arm, r_arm, q_h0, h_names, rng_i):
    lo, hi = float(rng_i[0]), float(rng_i[1])
    if hi - lo < 1e-6:
        return None
    values = np.linspace(lo + 0.1 * (hi - lo), hi - 0.1 * (hi - lo), 9)
    drift, err_static, err_refit = [], [], []
    for v in values:
        q_h = q_h0.copy()
        q_h[i] = v
        target = h_arm.pose(q_h)
        by_name = {n: np.array([q_h[k]]) for k, n in enumerate(h_names)}
        q_r = np.array([mm(by_name, 1)[0] for mm in maps])
        base = _pose_cost(r_arm, q_r, target)

        def cost(x, q_r=q_r, target=target):
            q = q_r.copy()
            q[j] = x
            return _pose_cost(r_arm, q, target)

        sol = minimize_scalar(cost, bounds=(q_r[j] - 1.0, q_r[j] + 1.0), method="bounded")
        drift.append(sol.x - q_r[j])
        err_static.append(np.sqrt(base))
        err_refit.append(np.sqrt(sol.fun))
    drift, x = np.asarray(drift), values - q_h0[i]
    # Linear in the source joint; the intercept is what the (possibly clipped) static b misses.
    coef = np.linalg.lstsq(np.stack([x, np.ones_like(x)], 1), drift, rcond=None)[0]
    gain, fit = float(coef[0]), coef[0] * x + coef[1]
    explained = 1.0 - np.sum((drift - fit) ** 2) / max(np.sum((drift - drift.mean()) ** 2), 1e-12)
    # Only a drift that matters to the eye: the static mapping is visibly off (> DRIFT_ERROR)
    # somewhere in the sweep and re-fitting this one joint removes a good part of that error.
    err_static, err_refit = np.asarray(err_static), np.asarray(err_refit)
    visible = err_static.max() > DRIFT_ERROR and err_refit.mean() < 0.75 * err_static.mean()
    if not visible or abs(gain) < 0.05 or explained < 0.8:
        return None
    return explained, gain


def _pose_cost(arm: _Arm, q: np.ndarray, target) -> float:
    return float(np.sum(_pose_residual(arm, q, target) ** 2))


def mapping_toml(robot: Robot, mapping: JointMapping) -> str:
    """The ``[mapping.left]`` / ``[mapping.right]`` tables of a robot toml."""
    lines = []
    for side in SIDES:
        lines.append(f"[mapping.{side}]")
        for name in robot.arm_joints[side]:
            m = mapping.get(name)
            fields = ([f'mmm = "{m.mmm}"'] if m.mmm and m.a else []) + [f"a = {m.a:.1f}", f"b = {_num(m.b)}"]
            if m.offset:
                fields.append(f'offset = {{ mmm = "{m.offset.mmm}", gain = {m.offset.gain} }}')
            lines.append(f"{name} = {{ {', '.join(fields)} }}")
        lines.append("")
    return "\n".join(lines)


def write_mapping(path: Path, text: str) -> None:
    """Replace the ``[mapping.*]`` tables of the robot toml ``path`` by ``text`` (appended if absent);
    every other line, comments included, stays as it was."""
    kept, skipping = [], False
    for line in path.read_text(encoding="utf-8").splitlines():
        header = line.strip().startswith("[") and not line.strip().startswith("[[")
        if header:
            skipping = line.strip().startswith("[mapping")
        if not skipping:
            kept.append(line)
    while kept and not kept[-1].strip():
        kept.pop()
    with atomic_path(path) as tmp:
        tmp.write_text("\n".join(kept) + "\n\n" + text, encoding="utf-8")


def _num(x: float) -> str:
    return repr(round(float(x), 6) + 0.0)
