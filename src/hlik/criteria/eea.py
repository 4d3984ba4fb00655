"""EEA and EEA^r: the elbow elevation (swivel) angle Ψ of an arm and its human-like prediction.

Ψ (formulas.md §1.1) is the rotation of the elbow about the shoulder -> wrist axis, measured from the
vertical plane through shoulder and wrist: 0 = elbow straight above the axis, π/2 = lateral
(outward, for both arms), π = straight below. It is computed in the arm frame of formulas.md §0
(x towards the arm's side, y forward, z up); inputs are in a frame with x right, y forward, z up
(the robot base frame, or the body frame of the MMM subject), so the left arm is mirrored
(x -> -x), which amounts to ``Ψ_left = -Ψ_raw mod 2π``.

Ψ is undefined when the arm is stretched (the elbow lies on the shoulder -> wrist axis) or when
that axis is vertical; :func:`swivel_angle` returns NaN there and callers reuse the last valid
value (:func:`forward_fill`). The cost of a NaN residual is NaN. Near either, Ψ is defined but
meaningless: a millimetre of elbow motion turns it by up to π (a Panda arm stretched at its elbow
limit crosses the axis and Ψ flips by π from one frame to the next), so the EEA residual is
weighted by :func:`swivel_weight`, which fades it to 0 there instead of switching at the exact
singularity.

Ψ_human (formulas.md §1.2) is Zanchettin's regression on the 6D hand pose, made linear in its
coefficients (:class:`SwivelPredictor`). Decisions: the hand orientation angles (θ, φ, ψ) are
``Rotation.from_matrix(R_arm).as_euler(EULER)`` of the TCP orientation in the arm frame, extrinsic
x, z, y; the published Euler convention is unknown, which is one reason to refit the coefficients
on MMM data (:meth:`SwivelPredictor.fit`) instead of using the printed ones. The sequence is chosen
for its gimbal lock (palm normal along the forward axis), which the KIT hands never come near
(≥ 47° away in 99 % of frames): roll-pitch-yaw ("xyz") locks with the palm facing down, where the
hands work (within 10° in 11.5 % of the frames), and there θ and ψ swing by up to π from one frame
to the next, and Ψ_human with them. The left
TCP orientation is mirrored as ``R_arm = D R diag(1, -1, 1)`` with ``D = diag(-1, 1, 1)`` (that is
``D R D Rz(π)``), so that mirror-symmetric hands, whose TCP frames both follow "z = approach,
x = palm normal, y = z × x", get identical features.

h_EEA (formulas.md §1.3) is ``d_θ(Ψ_robot, Ψ_human) / π`` averaged over both arms; the QP residual
is the signed, wrapped version of it (formulas.md §9).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from hlik.criteria.angles import wrap
from hlik.criteria.base import Criterion
from hlik.human.swivel import _SIDE_SIGN, TWO_PI, swivel_angle, swivel_parts
from hlik.robot.state import RobotState

# sine of the angle (upper arm to the shoulder -> wrist axis; that axis to the vertical) at which
# swivel_weight is 1/2: about 6 deg, where 1 mm of elbow motion turns Psi by ~0.03 rad
_FADE = 0.1
EULER = "xzy"  # extrinsic sequence of the hand orientation angles (module docstring)
_MIRROR = np.array([-1.0, 1.0, 1.0])  # x -> -x
_ARM_MIRROR = np.stack([_MIRROR, np.ones(3)])  # (2, 3): the left arm mirrored, the right as it is
# the left hand's D R diag(1, -1, 1) (_arm_frame) as an elementwise sign pattern
_HAND_MIRROR = np.stack([np.outer(_MIRROR, [1.0, -1.0, 1.0]), np.ones((3, 3))])
# bound on each arm's |dΨ/dq| (rad/rad) and on |dh_EEA/dq| (rad^-1, the same over π): the paper caps
# the elevation gradients (Sec. IV-A); they grow without bound near the singularities
SWIVEL_CAP = 20.0
GRADIENT_CAP = SWIVEL_CAP / np.pi

# The printed Zanchettin coefficients (RAM 2013, Eq. 3), in the terms they were printed in.
_PUBLISHED: dict[str, Any] = {
    "const": 1.39,
    "theta": (-0.88, 0.30),  # -0.88 cos(θ + 0.30)
    "theta_phi": (-0.49, 2.98),  # -0.49 cos(θ + φ + 2.98)
    "atan_zy": 0.21,
    "sin_psi": 0.64,
    "atan_xy": 0.50,
    "psi_theta_phi": 0.22,
    "phi": (-0.47, 0.60),  # -0.47 cos(φ + 0.60)
    "psi_theta": 0.40,
}

FEATURES = (
    "1",
    "cos θ",
    "sin θ",
    "cos(θ+φ)",
    "sin(θ+φ)",
    "atan2(z,y)",
    "sin ψ",
    "atan2(x,y)",
    "cos(ψ+θ+φ)",
    "cos φ",
    "sin φ",
    "cos(ψ+θ)",
)


def swivel_weight(shoulder: np.ndarray, elbow: np.ndarray, wrist: np.ndarray) -> np.ndarray:
    """How well Ψ is defined, (..., 2) in [0, 1]: 0 at the singularities, 1 away from them.

    ``s^4 / (s^4 + 0.1^4)`` for each of s = the sine of the upper arm's angle to the shoulder ->
    wrist axis and s = the sine of that axis' angle to the vertical, multiplied (0.94 at 0.2, 0.5
    at 0.1, 0.01 at 0.03).
    """
    return swivel_angle_and_weight(shoulder, elbow, wrist)[1]


def swivel_angle_and_weight(
    shoulder: np.ndarray, elbow: np.ndarray, wrist: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`swivel_angle` and :func:`swivel_weight` (each (..., 2)) from one pass."""
    parts = swivel_parts(shoulder, elbow, wrist)
    return _angle_and_weight(parts, np.asarray(elbow, float) - np.asarray(shoulder, float))


def _angle_and_weight(parts: tuple, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Ψ and the weight from :func:`~hlik.human.swivel.swivel_parts` and the upper arm ``b`` (..., 2, 3)."""
    psi_raw, singular, *_, eps2, _, sigma, _ = parts
    with np.errstate(invalid="ignore", divide="ignore"):
        s_elbow2 = eps2 / np.einsum("...i,...i->...", b, b)
    fade4 = _FADE**4
    weight = s_elbow2**2 / (s_elbow2**2 + fade4) * sigma**4 / (sigma**4 + fade4)
    return (_SIDE_SIGN * psi_raw) % TWO_PI, np.where(singular, 0.0, weight)


def swivel_gradient(
    shoulder: np.ndarray, elbow: np.ndarray, wrist: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Analytic dΨ/dshoulder, dΨ/delbow, dΨ/dwrist, each (..., 2, 3); NaN where Ψ is singular.

    With a = w - s, b = e - s, the frame (r, t = n × r, n) and b = X r + Y t + Z n, Ψ_raw =
    atan2(Y, X); then dΨ/db = (X t - Y r) / (X² + Y²) and, as n turns with a,
    dΨ/da = ((n·ẑ)/‖ẑ - (n·ẑ) n‖ t + Z (Y r - X t) / (X² + Y²)) / ‖a‖.
    """
    return _gradient_from_parts(swivel_parts(shoulder, elbow, wrist))


def _gradient_from_parts(parts: tuple) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`swivel_gradient` from :func:`~hlik.human.swivel.swivel_parts`."""
    _, singular, n, r, t, x, y, z, eps2, c, sigma, a_norm = parts
    with np.errstate(invalid="ignore", divide="ignore"):
        g_b = (x[..., None] * t - y[..., None] * r) / eps2[..., None]
        g_a = (c / sigma)[..., None] * t + z[..., None] * (y[..., None] * r - x[..., None] * t) / eps2[
            ..., None
        ]
        g_a = g_a / a_norm[..., None]
    sign = np.where(singular, np.nan, _SIDE_SIGN)[..., None]
    g_a = sign * g_a
    g_b = sign * g_b
    return -g_a - g_b, g_b, g_a


def swivel_jacobian(state: RobotState, cap: float = SWIVEL_CAP) -> np.ndarray:
    """dΨ/dq (F, 2, n) through the shoulder, elbow and wrist position Jacobians of ``state``.

    Each arm's row is scaled down to norm ``cap`` (rad/rad) if it is longer: the gradient grows
    without bound near the singularities (the paper caps it too). Rows where Ψ is singular are 0.
    """
    if state.jac is None:
        raise ValueError("swivel_jacobian needs a RobotState with Jacobians (jacobians=True)")
    return _capped(_chained(swivel_gradient(state.shoulder, state.elbow, state.wrist), state.jac), cap)


def _chained(grads: tuple[np.ndarray, ...], jac: np.ndarray) -> np.ndarray:
    """dΨ/dq (F, 2, n) from dΨ/dshoulder, /delbow, /dwrist (each (F, 2, 3)) and the site Jacobians
    (F, 2, sites, 6, n); 0 where Ψ is singular."""
    d_psi = sum(np.einsum("fak,fakn->fan", g, jac[:, :, i, :3, :]) for i, g in enumerate(grads))
    return np.nan_to_num(d_psi, nan=0.0, posinf=0.0, neginf=0.0)


def _capped(jac: np.ndarray, cap: float) -> np.ndarray:
    """Each row of ``jac`` (..., n) scaled down to norm ``cap`` if it is longer."""
    norm = np.linalg.norm(jac, axis=-1, keepdims=True)
    return jac * np.minimum(1.0, cap / np.maximum(norm, 1e-300))


# --- the human-like prediction Ψ_human -------------------------------------------------------


def _arm_frame(shoulder: np.ndarray, tcp_pos: np.ndarray, tcp_rot: np.ndarray):
    """Hand position relative to the shoulder (..., 2, 3) and orientation (..., 2, 3, 3), arm frame."""
    p = (np.asarray(tcp_pos, float) - np.asarray(shoulder, float)) * _ARM_MIRROR  # left arm: x -> -x
    # Left arm: reflect the axes (D R) and restore y = z × x of the TCP frame convention
    # (z approach, x palm normal; robots/README.md), i.e. D R D Rz(π). Plain D R D would leave a
    # symmetric left hand rotated by π about its approach axis relative to the right one.
    return p, np.asarray(tcp_rot, float) * _HAND_MIRROR


def euler_xzy(rot: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Extrinsic x-z-y Euler angles (each (...,)) of rotations (..., 3, 3): R = R_y(c) R_z(b) R_x(a),
    b in [-π/2, π/2]; SciPy's ``as_euler("xzy")`` away from its gimbal lock (b = ±π/2), in closed
    form (SciPy's object costs more than the whole criterion here)."""
    a = np.arctan2(-rot[..., 1, 2], rot[..., 1, 1])
    b = np.arcsin(np.clip(rot[..., 1, 0], -1.0, 1.0))
    c = np.arctan2(-rot[..., 2, 0], rot[..., 0, 0])
    return a, b, c


@dataclass(frozen=True, eq=False)
class SwivelPredictor:
    """Ψ_human = coef · features(hand pose), Zanchettin's regressor structure (formulas.md §1.2).

    Attributes:
        coef: (12,) coefficients of :data:`FEATURES`.
    """

    coef: np.ndarray

    @staticmethod
    def features(shoulder: np.ndarray, tcp_pos: np.ndarray, tcp_rot: np.ndarray) -> np.ndarray:
        """(..., 2, 12) regressors from (..., 2, 3) shoulder and TCP positions, (..., 2, 3, 3) TCP rotations.

        Inputs are in a frame with x right, y forward, z up; the left arm is mirrored into its arm
        frame. (x, y, z) is the TCP relative to the shoulder; (θ, φ, ψ) are the extrinsic
        :data:`EULER` angles of the TCP orientation.
        """
        p, rot = _arm_frame(shoulder, tcp_pos, tcp_rot)
        th, ph, ps = euler_xzy(rot)
        x, y, z = p[..., 0], p[..., 1], p[..., 2]
        out = np.empty((*th.shape, len(FEATURES)))
        out[..., 0] = 1.0
        out[..., 1], out[..., 2] = np.cos(th), np.sin(th)
        out[..., 3], out[..., 4] = np.cos(th + ph), np.sin(th + ph)
        out[..., 5] = np.arctan2(z, y)
        out[..., 6] = np.sin(ps)
        out[..., 7] = np.arctan2(x, y)
        out[..., 8] = np.cos(ps + th + ph)
        out[..., 9], out[..., 10] = np.cos(ph), np.sin(ph)
        out[..., 11] = np.cos(ps + th)
        return out

    def predict(self, shoulder: np.ndarray, tcp_pos: np.ndarray, tcp_rot: np.ndarray) -> np.ndarray:
        """Ψ_human (..., 2) in [0, 2π)."""
        return (self.features(shoulder, tcp_pos, tcp_rot) @ self.coef) % TWO_PI

    @classmethod
    def published(cls) -> SwivelPredictor:
        """The printed Zanchettin coefficients, with cos(a + c) = cos c cos a - sin c sin a expanded."""
        p = _PUBLISHED

        def shifted(key: str) -> tuple[float, float]:
            k, c = p[key]
            return k * np.cos(c), -k * np.sin(c)

        coef = [
            p["const"],
            *shifted("theta"),
            *shifted("theta_phi"),
            p["atan_zy"],
            p["sin_psi"],
            p["atan_xy"],
            p["psi_theta_phi"],
            *shifted("phi"),
            p["psi_theta"],
        ]
        return cls(np.array(coef))

    @classmethod
    def fit(
        cls,
        shoulder: np.ndarray,
        elbow: np.ndarray,
        wrist: np.ndarray,
        tcp_pos: np.ndarray,
        tcp_rot: np.ndarray,
    ) -> tuple[SwivelPredictor, float]:
        """Least-squares fit of the 12 coefficients to the swivel angles of human data.

        Args: (T, 2, 3) joint centres and TCP positions, (T, 2, 3, 3) TCP rotations (both arms
        pooled; frame as in :meth:`features`).

        Returns:
            The predictor and the RMS of its wrapped prediction error in rad.
        """
        psi = swivel_angle(shoulder, elbow, wrist).ravel()
        feats = cls.features(shoulder, tcp_pos, tcp_rot).reshape(-1, len(FEATURES))
        keep = np.isfinite(psi) & np.all(np.isfinite(feats), axis=-1)
        if not np.any(keep):
            raise ValueError("no frame with a defined swivel angle to fit")
        coef = np.linalg.lstsq(feats[keep], psi[keep], rcond=None)[0]
        err = wrap(feats[keep] @ coef - psi[keep])
        return cls(coef), float(np.sqrt(np.mean(err**2)))


# --- exact derivatives of the prediction and the weight (SLSQP, JV) ----------------------------

_EPS = 1e-6
_AXES = np.concatenate([np.eye(3), -np.eye(3)])  # +x, +y, +z, -x, -y, -z
# rows of _stepped's 13 at +eps and at -eps along x, y, z: block 0, then block 1
_PLUS, _MINUS = [1, 2, 3, 7, 8, 9], [4, 5, 6, 10, 11, 12]


def _step_tables() -> tuple[np.ndarray, np.ndarray]:
    """Per block (0, 1), the 13 moves (2, 13, 1, 1, 3) and turns (2, 13, 1, 1, 3, 3) of
    :func:`_stepped`: none in row 0 and in the other block's rows."""
    moves, turns = np.zeros((2, 13, 1, 1, 3)), np.tile(np.eye(3), (2, 13, 1, 1, 1, 1))
    # world-frame turns, left-multiplied: the angular rows of the site Jacobian are world-frame
    rotations = Rotation.from_rotvec(_EPS * _AXES).as_matrix()
    for block in (0, 1):
        rows = slice(1 + 6 * block, 7 + 6 * block)
        moves[block, rows, 0, 0] = _EPS * _AXES
        turns[block, rows, 0, 0] = rotations
    return moves, turns


_MOVES, _TURNS = _step_tables()


def _stepped(x: np.ndarray, block: int) -> np.ndarray:
    """13 rows of ``x`` (F, 2, 3) or (F, 2, 3, 3): ``x``, then two blocks of 6 in which ``x`` is
    moved (points) or turned (rotations) by ±:data:`_EPS` about each axis in block ``block`` (0 or
    1) and held in the other."""
    return _TURNS[block] @ x[None] if x.ndim == 4 else x[None] + _MOVES[block]


def prediction_and_jacobian(predictor: SwivelPredictor, state: RobotState) -> tuple[np.ndarray, np.ndarray]:
    """Ψ_human (F, 2) and dΨ_human/dq (F, 2, n): central differences of the closed-form prediction
    in the TCP position relative to the shoulder and in a small world-frame rotation of the TCP,
    chained through the site Jacobians; one vectorised call of the regressor (13 rows: the
    configuration, 6 moves, 6 turns), no kinematics. The differences are wrapped, so Ψ's 2π cut
    does not show."""
    if state.jac is None:
        raise ValueError("prediction_and_jacobian needs a RobotState with Jacobians (jacobians=True)")
    pos, rot = _stepped(state.tcp, 0), _stepped(state.tcp_rot, 1)  # 6 moves, then 6 turns of the TCP
    psi = predictor.predict(np.broadcast_to(state.shoulder, pos.shape), pos, rot)  # (13, F, 2)
    d = wrap(psi[_PLUS] - psi[_MINUS]) / (2 * _EPS)  # (6, F, 2)
    jac = state.jac
    rel = jac[:, :, 3, :3, :] - jac[:, :, 0, :3, :]  # TCP relative to the shoulder
    d_psi = np.einsum("kfa,fakn->fan", d[:3], rel) + np.einsum("kfa,fakn->fan", d[3:], jac[:, :, 3, 3:, :])
    return psi[0], d_psi


def _weight_gradient(parts: tuple, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """d weight / da and d weight / db (each (..., 2, 3)) of :func:`swivel_weight`, a the shoulder ->
    wrist and b the shoulder -> elbow vector, from :func:`~hlik.human.swivel.swivel_parts`.

    The weight is ``F(u) G(sigma)`` with u = 1 - z²/|b|² the squared sine of the upper arm to the
    axis (z = b . n) and sigma = sqrt(1 - c²) the sine of the axis to the vertical (c = n . up), so
    ``du/db = 2 (z² b / |b|² - z n) / |b|²``, ``du/da = -2 z (b - z n) / (|a| |b|²)`` and
    ``dsigma/da = -c r / |a|`` (r the unit of up - c n).
    """
    _, _, n, r, _, _, _, z, eps2, c, sigma, a_norm = parts
    f4 = _FADE**4
    with np.errstate(invalid="ignore", divide="ignore"):
        bb = np.einsum("...i,...i->...", b, b)
        u = eps2 / bb
        f_u, g_s = u**2 / (u**2 + f4), sigma**4 / (sigma**4 + f4)
        df = 2.0 * u * f4 / (u**2 + f4) ** 2 * g_s
        dg = 4.0 * sigma**3 * f4 / (sigma**4 + f4) ** 2 * f_u
        zc = (z / bb)[..., None]
        d_b = (2.0 * df[..., None] / bb[..., None]) * (zc * z[..., None] * b - z[..., None] * n)
        d_a = (
            -2.0 * df[..., None] * zc * (b - z[..., None] * n) - dg[..., None] * c[..., None] * r
        ) / a_norm[..., None]
    return d_a, d_b


def swivel_parts_and_jacobians(state: RobotState) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Ψ (F, 2), :func:`swivel_weight` (F, 2), its derivative d weight / dq (F, 2, n) and the
    uncapped dΨ/dq (F, 2, n) of ``state``, from one pass over the arm geometry: both are functions
    of the shoulder -> wrist and shoulder -> elbow vectors (:func:`swivel_gradient`,
    :func:`_weight_gradient`), chained through the site Jacobians in one product; 0 where Ψ is
    singular."""
    if state.jac is None:
        raise ValueError("swivel_parts_and_jacobians needs a RobotState with Jacobians (jacobians=True)")
    b = state.elbow - state.shoulder
    parts = swivel_parts(state.shoulder, state.elbow, state.wrist)
    psi, w = _angle_and_weight(parts, b)
    d = np.empty((*psi.shape, 2, 2, 3))  # (F, 2, [Ψ, weight], [a, b], 3)
    _, d[..., 0, 1, :], d[..., 0, 0, :] = _gradient_from_parts(parts)
    d[..., 1, 0, :], d[..., 1, 1, :] = _weight_gradient(parts, b)
    jac = state.jac[:, :, :, :3, :]
    ab = jac[:, :, [2, 1]] - jac[:, :, [0]]  # (F, 2, [a, b], 3, n): wrist, elbow relative to the shoulder
    d_q = np.einsum("faqjk,fajkn->faqn", d, ab)
    d_q[~np.isfinite(d_q)] = 0.0
    return psi, w, d_q[:, :, 1], d_q[:, :, 0]


# --- the criterion ---------------------------------------------------------------------------


def eea_residual(psi: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Signed normalised EEA residual (..., 2): wrap(Ψ - target) / π, in [-1, 1)."""
    return wrap(np.asarray(psi) - np.asarray(target)) / np.pi


def eea_cost(residual: np.ndarray) -> np.ndarray:
    """h_EEA (...): the mean over both arms of |residual|; NaN if a residual is NaN."""
    return np.mean(np.abs(residual), axis=-1)


def eea_r_target(psi: np.ndarray, psi_human: np.ndarray, psi_mmm: np.ndarray) -> np.ndarray:
    """The EEA^r target (..., 2): whichever of Ψ_human and Ψ_MMM is angularly nearer to Ψ.

    So ``eea_cost(eea_residual(psi, target))`` per arm equals
    ``min(h_EEA, d_θ(Ψ, Ψ_MMM) / π)``. A NaN candidate loses to a finite one.
    """
    d_h = np.abs(wrap(np.asarray(psi) - psi_human))
    d_m = np.abs(wrap(np.asarray(psi) - psi_mmm))
    use_mmm = (d_m < d_h) | (np.isnan(d_h) & ~np.isnan(d_m))
    return np.where(use_mmm, psi_mmm, psi_human)


class EEA(Criterion):
    """EEA: each arm's elbow elevation Ψ to the human-like prediction Ψ_human (e (F, 2)).

    e = :func:`swivel_weight` · wrap(Ψ - Ψ_human) / π: toward a stretched arm or a vertical
    shoulder -> wrist axis the residual and its row of the Jacobian fade to 0, as there is no
    elevation to compare. The prediction and the weight are held fixed in :meth:`jacobian` (the
    QP's Gauss-Newton step, formulas.md §9); each factor of the weight is above 0.99 beyond 19° from
    its singularity. :meth:`exact` (SLSQP, JV) is exact: it adds the prediction's and the weight's
    derivatives (:func:`prediction_and_jacobian`, :func:`swivel_parts_and_jacobians`); the
    gradients of h it gives (:mod:`hlik.solvers.gradients`) are capped at :data:`GRADIENT_CAP` in
    norm as the paper caps the elevation gradients (Sec. IV-A).
    """

    name, gamma, x0, weight = "EEA", 4.0, 0.3, 1 / 20
    exact_jacobian = False  # jacobian() holds the prediction and the weight fixed; exact() does not
    needs_sample, parts, part_form = False, 2, "norm"
    gradient_cap = GRADIENT_CAP

    learned = "swivel"

    def __init__(self, robot: object, swivel: SwivelPredictor):
        self.swivel = swivel

    def target(self, state: RobotState, sample: object, psi: np.ndarray) -> np.ndarray:
        """(F, 2) the Ψ each arm is drawn to."""
        return self.swivel.predict(state.shoulder, state.tcp, state.tcp_rot)

    def residual(self, state, sample):
        psi, weight = swivel_angle_and_weight(state.shoulder, state.elbow, state.wrist)
        return weight * np.nan_to_num(eea_residual(psi, self.target(state, sample, psi)))

    def jacobian(self, state, sample):
        weight = swivel_weight(state.shoulder, state.elbow, state.wrist)
        return weight[..., None] * swivel_jacobian(state) / np.pi

    def cost(self, e):
        return eea_cost(e)

    def cost_gradient(self, e):
        return np.sign(e) / e.shape[-1]

    def target_and_jacobian(
        self, state: RobotState, sample: object, psi: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """The target (F, 2) and its derivative d target / dq (F, 2, n)."""
        return prediction_and_jacobian(self.swivel, state)

    def exact(self, state, sample):
        # one pass each over the arm geometry and the regressor (13 rows): SLSQP calls this per evaluation
        psi, weight, d_weight, d_swivel = swivel_parts_and_jacobians(state)
        target, d_target = self.target_and_jacobian(state, sample, psi)
        r = eea_residual(psi, target)
        r[np.isnan(r)] = 0.0
        d_psi = _capped(d_swivel, SWIVEL_CAP) - d_target
        jac = d_weight * r[..., None] + weight[..., None] * d_psi / np.pi  # (1, 2, n)
        return (weight * r)[0], jac[0]


class EEA_r(EEA):  # noqa: N801 - the paper's name
    """EEA^r: as EEA, toward whichever of Ψ_human and the recorded human's Ψ_MMM is nearer."""

    name, gamma, x0, weight = "EEA_r", 6.0, 0.1, 1 / 20
    needs_sample = True

    def target(self, state, sample, psi):
        return eea_r_target(psi, super().target(state, sample, psi), sample.psi_mmm)

    def target_and_jacobian(self, state, sample, psi):
        human, d_human = super().target_and_jacobian(state, sample, psi)
        target = eea_r_target(psi, human, sample.psi_mmm)
        moving = target == human  # the recorded Ψ_MMM does not move
        return target, np.where(moving[..., None], d_human, 0.0)
