"""Capture through a compliant 6-DoF interface between a servicer frame a and a client frame b.

Not in Vicariotto 2023 (the thesis has no contact model, its §6 docking regulates the relative pose); this
module adds a spring-damper on SE(3) that joins the two frames from the capture time t_c on.

Conventions (DESIGN §3): one Pinocchio model holds both spacecraft; poses are SE3 world<-frame
(``g_a = oMf[a]``); twists ``[v; ω]`` (m/s, rad/s) and wrenches ``[f; τ]`` (N, N m) are in a frame's LOCAL
axes at its origin. ``Ad_{b←a} = Ad_{g_b⁻¹ g_a}`` maps a twist of frame a into frame b.

- Relative twist (frame b): ``V_rel = V_b − Ad_{b←a} V_a = J_rel v`` with ``J_rel = J_b − Ad_{b←a} J_a``.
- Pose error: ``g_e = g_t⁻¹ g_a⁻¹ g_b`` (b relative to its target pose ``g_t = g_ab_target`` in frame a),
  ``e = log6(g_e)``; ``g_e⁻¹ ġ_e = V_rel`` so ``ė = Jlog6(g_e) V_rel``.
- Interface: ``U = ½ eᵀ K e`` (J); ``F_b = −Jlog6(g_e)ᵀ K e − D V_rel`` at b; ``F_a = −Ad_{b←a}ᵀ F_b`` at a.
  The pair does no net work but ``−dU/dt − V_relᵀ D V_rel`` (the spring is exactly conservative), and
  transported to the world the two wrenches cancel (total momentum is conserved).
- Relative operational inertia ``Λ_rel = (J_rel M⁻¹ J_relᵀ)⁻¹`` (6x6, frame b): at rest, a wrench pair
  (F_b, F_a) as above gives ``V̇_rel = Λ_rel⁻¹ F_b``.
- Gains frozen at t_c: ``K = ω² Λ_rel``, ``D = 2ζω Λ_rel``; the linearised interface
  ``Λ_rel ë + D ė + K e = 0`` then has the generalized eigenvalues ``K x = λ Λ_rel x`` all equal to ω²:
  every one of its six modes rings at f = ω/2π with damping ratio ζ.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from sms_cli.errors import InputError, Location, NumericalError, Problem
from sms_cli.model.system import symmetric_from_crba
from sms_cli.formation.plant import joint_forces, system_momentum  # noqa: F401  (one implementation, re-exported)

STEPS_PER_PERIOD = 20  # plant steps needed per period of the interface's natural frequency


def frame_id(model: pin.Model, frame: int | str) -> int:
    """The id of a frame given by id or name; an unknown name is an ``InputError``."""
    if isinstance(frame, str):
        if not model.existFrame(frame):
            names = [f.name for f in model.frames]
            close = [n for n in names if frame.lower() in n.lower() or n.lower() in frame.lower()]
            hint = f"did you mean '{close[0]}'?" if close else "frames: " + ", ".join(names[:12])
            raise InputError(problems=[Problem(f"no frame named '{frame}' in the model", None, "capture", hint)])
        return model.getFrameId(frame)
    if not 0 <= int(frame) < model.nframes:
        raise InputError(problems=[Problem(f"frame id {frame} is outside 0..{model.nframes - 1}", None, "capture")])
    return int(frame)


def _mass_matrix(model: pin.Model, data: pin.Data, q: np.ndarray) -> np.ndarray:
    """Joint-space inertia M(q) (nv x nv, SI) from CRBA, symmetrised (CRBA fills the upper triangle)."""
    return symmetric_from_crba(pin.crba(model, data, q))


def relative_jacobian(model: pin.Model, data: pin.Data, q: np.ndarray, frame_a: int | str,
                      frame_b: int | str) -> np.ndarray:
    """J_rel = J_b − Ad_{b←a} J_a (6 x nv, frame b): ``V_rel = J_rel v``. Updates the kinematics in ``data``."""
    fa, fb = frame_id(model, frame_a), frame_id(model, frame_b)
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    J_a = pin.getFrameJacobian(model, data, fa, pin.LOCAL)
    J_b = pin.getFrameJacobian(model, data, fb, pin.LOCAL)
    g_ba = data.oMf[fb].actInv(data.oMf[fa])
    return J_b - g_ba.action @ J_a


def relative_operational_inertia(model: pin.Model, data: pin.Data, q: np.ndarray, frame_a: int | str,
                                 frame_b: int | str) -> np.ndarray:
    """Λ_rel = (J_rel M⁻¹ J_relᵀ)⁻¹ (6x6, frame b; kg, kg m, kg m²) at configuration q.

    Raises ``NumericalError`` when the two frames cannot move relative to each other in all six directions
    (J_rel M⁻¹ J_relᵀ singular), e.g. when they ride on the same rigid body."""
    J_rel = relative_jacobian(model, data, q, frame_a, frame_b)
    J_b = pin.getFrameJacobian(model, data, frame_id(model, frame_b), pin.LOCAL)
    M = _mass_matrix(model, data, q)
    X = np.linalg.solve(M, np.hstack([J_rel.T, J_b.T]))
    inv_lambda = J_rel @ X[:, :6]
    inv_lambda = 0.5 * (inv_lambda + inv_lambda.T)
    scale = np.linalg.eigvalsh(J_b @ X[:, 6:])[-1]  # frame b's own mobility: what "small" is measured against
    if np.linalg.eigvalsh(inv_lambda)[0] <= 1e-9 * scale:
        name_a, name_b = (model.frames[frame_id(model, f)].name for f in (frame_a, frame_b))
        raise NumericalError(problems=[Problem(
            f"frames '{name_a}' and '{name_b}' cannot move relative to each other in all six directions"
            " (relative operational inertia singular)",
            None, "capture", "join frames of the two spacecraft, not two frames of one rigid body")])
    lam = np.linalg.inv(inv_lambda)
    return 0.5 * (lam + lam.T)


@dataclass(frozen=True)
class InterfaceGains:
    """Stiffness K (6x6, N/m, N m/rad and couplings) and damping D (6x6, N s/m, N m s/rad) in the error
    coordinates e = log6(g_e) and the relative twist V_rel (frame b); both symmetric."""

    K: np.ndarray
    D: np.ndarray

    @classmethod
    def from_frequency(cls, lambda_rel: np.ndarray, natural_frequency_hz: float,
                       damping_ratio: float) -> "InterfaceGains":
        """K = ω² Λ_rel, D = 2ζω Λ_rel with ω = 2π f (Λ_rel frozen at the capture time): every mode of the
        linearised interface then oscillates at f (K x = λ Λ_rel x has λ = ω² six times)."""
        problems = []
        if not (math.isfinite(natural_frequency_hz) and natural_frequency_hz > 0):
            problems.append(Problem(f"the interface natural frequency must be positive, got {natural_frequency_hz} Hz",
                                    None, "capture.frequency"))
        if not (math.isfinite(damping_ratio) and damping_ratio >= 0):
            problems.append(Problem(f"the interface damping ratio must be ≥ 0, got {damping_ratio}",
                                    None, "capture.damping_ratio"))
        if problems:
            raise InputError(problems=problems)
        lam = 0.5 * (np.asarray(lambda_rel, float) + np.asarray(lambda_rel, float).T)
        w = 2.0 * math.pi * natural_frequency_hz
        return cls(K=w * w * lam, D=2.0 * damping_ratio * w * lam)


def _fmt_floor(x: float, digits: int = 2) -> str:
    """x rounded DOWN to ``digits`` significant digits, so that the printed bound still satisfies it."""
    e = math.floor(math.log10(x)) - digits + 1
    s = f"{math.floor(x / 10.0**e * (1 + 1e-12)) * 10.0**e:.{max(0, -e)}f}"
    return s.rstrip("0").rstrip(".") if "." in s else s


def check_resolution(dt: float, natural_frequency_hz: float, where: Location | None, field: str = "") -> None:
    """Refuse (``InputError``, exit 2) a plant step dt (s) coarser than T/20, T = 1/f the interface period."""
    for value, what in ((dt, "the simulation step"), (natural_frequency_hz, "the interface frequency")):
        if not (math.isfinite(value) and value > 0):
            raise InputError(problems=[Problem(f"{what} must be positive, got {value:g}", where, field)])
    steps = 1.0 / (natural_frequency_hz * dt)
    if steps * (1 + 1e-12) >= STEPS_PER_PERIOD:
        return
    need = 1.0 / (STEPS_PER_PERIOD * natural_frequency_hz)
    f_max = 1.0 / (STEPS_PER_PERIOD * dt)
    raise InputError(problems=[Problem(
        f"plant step {dt:g} s resolves the {natural_frequency_hz:g} Hz capture interface with {steps:.1f} steps per"
        f" period; it needs ≥ {STEPS_PER_PERIOD}: set simulation dt ≤ {_fmt_floor(need)} s or lower the interface"
        f" frequency to ≤ {_fmt_floor(f_max)} Hz", where, field,
        f"the interface period is T = 1/f = {1.0 / natural_frequency_hz:.4g} s;"
        f" the step must be ≤ T/{STEPS_PER_PERIOD}")])


def pose_error(g_a: pin.SE3, g_b: pin.SE3, g_ab_target: pin.SE3) -> pin.SE3:
    """g_e = g_t⁻¹ g_a⁻¹ g_b: the pose of frame b relative to its target pose (identity when joined)."""
    return g_ab_target.actInv(g_a.actInv(g_b))


def capture_offset(g_a: pin.SE3, g_b: pin.SE3, g_ab_target: pin.SE3) -> tuple[float, float]:
    """(distance m, angle deg) of frame b from its target pose relative to frame a (from g_e)."""
    g_e = pose_error(g_a, g_b, g_ab_target)
    angle = float(np.linalg.norm(pin.log3(g_e.rotation)))
    return float(np.linalg.norm(g_e.translation)), math.degrees(angle)


def check_capture_offset(g_a: pin.SE3, g_b: pin.SE3, g_ab_target: pin.SE3, t: float, tolerance_m: float,
                         tolerance_deg: float, name_a: str = "end effector",
                         name_b: str = "grapple fixture") -> tuple[float, float]:
    """The capture offset, or ``NumericalError`` (exit 3) when the distance or the angle exceeds its tolerance."""
    d, a = capture_offset(g_a, g_b, g_ab_target)
    if d > tolerance_m or a > tolerance_deg:
        raise NumericalError(problems=[Problem(
            f"at the capture time t = {t:.1f} s the {name_a} is {d:.3f} m and {a:.1f} deg from the {name_b};"
            f" tolerance {tolerance_m:g} m / {tolerance_deg:g} deg", None, "capture",
            "bring the approach closer to the capture pose before t_c, or move the capture time")])
    return d, a


def _interface_state(model: pin.Model, data: pin.Data, q: np.ndarray, v: np.ndarray | None, fa: int, fb: int,
                     g_ab_target: pin.SE3):
    if v is None:
        pin.framesForwardKinematics(model, data, q)
        V_rel = None
    else:
        pin.forwardKinematics(model, data, q, v)
        pin.updateFramePlacements(model, data)
    g_a, g_b = data.oMf[fa], data.oMf[fb]
    g_ba = g_b.actInv(g_a)
    if v is not None:
        V_a = pin.getFrameVelocity(model, data, fa, pin.LOCAL).vector
        V_b = pin.getFrameVelocity(model, data, fb, pin.LOCAL).vector
        V_rel = V_b - g_ba.action @ V_a
    return pose_error(g_a, g_b, g_ab_target), g_ba, V_rel


def interface_energy(model: pin.Model, data: pin.Data, q: np.ndarray, frame_a: int | str, frame_b: int | str,
                     g_ab_target: pin.SE3, gains: InterfaceGains) -> float:
    """U = ½ eᵀ K e (J), e = log6(g_t⁻¹ g_a⁻¹ g_b)."""
    g_e, _, _ = _interface_state(model, data, q, None, frame_id(model, frame_a), frame_id(model, frame_b),
                                 g_ab_target)
    e = pin.log6(g_e).vector
    return 0.5 * float(e @ gains.K @ e)


def interface_wrenches(model: pin.Model, data: pin.Data, q: np.ndarray, v: np.ndarray, frame_a: int | str,
                       frame_b: int | str, g_ab_target: pin.SE3,
                       gains: InterfaceGains) -> list[tuple[int, np.ndarray]]:
    """[(frame_a, F_a), (frame_b, F_b)]: the interface wrenches [f; τ] (N, N m) on each frame, in its LOCAL axes at
    its origin. F_b = −Jlog6(g_e)ᵀ K e − D V_rel; F_a = −Ad_{b←a}ᵀ F_b (equal and opposite)."""
    fa, fb = frame_id(model, frame_a), frame_id(model, frame_b)
    g_e, g_ba, V_rel = _interface_state(model, data, q, v, fa, fb, g_ab_target)
    e = pin.log6(g_e).vector
    F_b = -pin.Jlog6(g_e).T @ (gains.K @ e) - gains.D @ V_rel
    F_a = -g_ba.action.T @ F_b
    return [(fa, F_a), (fb, F_b)]


def locked_twist(model: pin.Model, data: pin.Data, q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The stack's locked twist [v_G; ω_L] (m/s, rad/s): world axes, at the system CoM G.

    ``ω_L = I_G⁻¹ L_G`` with I_G the composite inertia of every body about G (the whole system frozen in its
    current shape) and L_G the angular momentum about G; v_G the CoM velocity. Once the interface has damped the
    relative motion the joined stack turns rigidly at ω_L."""
    pin.ccrba(model, data, q, v)
    Ig = data.Ig.matrix()
    h_g = data.hg.vector
    return np.linalg.solve(Ig, h_g)


@dataclass(frozen=True)
class CaptureMetrics:
    """Figures of one capture (SI).

    peak_force_N, peak_torque_Nm: largest |f| and |τ| of the interface wrench that either frame feels at its own
    origin after t_c. stack_twist: the locked twist [v_G; ω_L] at the end of the run (world axes, at the CoM);
    stack_rate_base: ω_L (rad/s) in the axes of the first free-flyer (the servicer's base). momentum_before /
    momentum_after: ``system_momentum`` at t_c and at the end. offset_m, offset_deg: capture offset at t_c."""

    t_capture: float
    peak_force_N: float
    peak_torque_Nm: float
    stack_twist: np.ndarray
    stack_rate_base: np.ndarray
    momentum_before: np.ndarray
    momentum_after: np.ndarray
    offset_m: float
    offset_deg: float


@dataclass
class CaptureMonitor:
    """Collects the capture figures while a loop steps the model: ``at_capture`` once at t_c, ``sample`` at each
    step with the wrenches applied, ``finish`` at the end."""

    model: pin.Model
    t_capture: float = 0.0
    offset: tuple[float, float] = (math.nan, math.nan)
    momentum_before: np.ndarray = field(default_factory=lambda: np.full(6, np.nan))
    peak_force: float = 0.0
    peak_torque: float = 0.0

    def at_capture(self, data: pin.Data, t: float, q: np.ndarray, v: np.ndarray, frame_a: int | str,
                   frame_b: int | str, g_ab_target: pin.SE3) -> None:
        """Record the momentum and the offset at the capture time t (s)."""
        self.t_capture = float(t)
        self.momentum_before = system_momentum(self.model, data, q, v)
        pin.framesForwardKinematics(self.model, data, q)
        fa, fb = frame_id(self.model, frame_a), frame_id(self.model, frame_b)
        self.offset = capture_offset(data.oMf[fa], data.oMf[fb], g_ab_target)

    def sample(self, wrenches: list[tuple[int, np.ndarray]]) -> None:
        """Update the peaks with the interface wrenches of one step."""
        for _, F in wrenches:
            self.peak_force = max(self.peak_force, float(np.linalg.norm(F[:3])))
            self.peak_torque = max(self.peak_torque, float(np.linalg.norm(F[3:])))

    def finish(self, data: pin.Data, q: np.ndarray, v: np.ndarray) -> CaptureMetrics:
        """The metrics, with the momentum and the stack twist of the final state."""
        twist = locked_twist(self.model, data, q, v)
        base = next((j for j in range(1, self.model.njoints)
                     if self.model.joints[j].shortname() == "JointModelFreeFlyer"), 1)
        pin.forwardKinematics(self.model, data, q)
        R_base = data.oMi[base].rotation
        return CaptureMetrics(self.t_capture, self.peak_force, self.peak_torque, twist, R_base.T @ twist[3:],
                              self.momentum_before, system_momentum(self.model, data, q, v), *self.offset)
