"""Relative (locked/shape) control of two spacecraft, Vicariotto 2023 §5.4, in a passivity form derived
here from the decomposition (5.7) so that its Lyapunov function decreases exactly.

Quantities (``sms_cli.formation.decomposition``; body 1 = the master): ξ_i the locked twist of body i
(its base frame), V_L = ξ1 + A*V_E (frame 1) and V_E = ξ2 − Ad⁻¹ξ1 (frame 2) the locked and shape
twists, M_L, M_E their inertias; θ̇_i the wheel rates of body i and Λ_i = M_bb,i⁻¹ M_bθ,i (6 × n_i) its
mechanical connection, so that its true base twist is V_i = ξ_i − Λ_i θ̇_i.

Potentials (Bullo–Murray on SE(3), Vicariotto 2023 L978, L1002): U(g; g_d) = ½ rᵀK_p r + ½ tr(K_R(1 − R_e))
with R_e = R_dᵀR, r = R_dᵀ(p − p_d); its gradient in the body frame ∇U = [R_eᵀK_p r; γ], γ = (skew(K_R R_e))^∨
(4.11), so that U̇ = ∇Uᵀ V for the body twist V of g. U_L on the master's pose g1, U_E on the relative pose
g12 = g1⁻¹g2 (whose body twist is V_E − Λ2θ̇2 + Ad⁻¹Λ1θ̇1).

With generalized forces [F_L; F_E; τ_w1 − Λ1ᵀF1; τ_w2 − Λ2ᵀF2] (the (5.7) right-hand side) the kinetic
energy T of the pair changes at their power, so W = T + U_L + U_E has

  Ẇ = V_Lᵀ(F_L + ∇U_L) + V_Eᵀ(F_E + ∇U_E − A*ᵀ∇U_L)
      + θ̇1ᵀ(τ_w1 − Λ1ᵀF1 − Λ1ᵀ∇U_L + Λ1ᵀAd⁻ᵀ∇U_E) + θ̇2ᵀ(τ_w2 − Λ2ᵀF2 − Λ2ᵀ∇U_E).

The free-flying law (the PD+ of (5.11)) takes, for the controlled subsystems,

  F_L = −∇U_L − K_L V_L + C_LE V_E,   F_E = −∇U_E + A*ᵀ∇U_L − K_E V_E + C_EL V_L,
  τ_w1 = Λ1ᵀF1 + Λ1ᵀ∇U_L − Λ1ᵀAd⁻ᵀ∇U_E − K_w θ̇1,   τ_w2 = Λ2ᵀF2 + Λ2ᵀ∇U_E − K_w θ̇2,

and Ẇ = −V_LᵀK_LV_L − V_EᵀK_EV_E − K_w|θ̇|² ≤ 0 (an uncontrolled subsystem has no potential and, for the
locked one, F_L = 0). The feed-forwards C_LE V_E and C_EL V_L (the coupling blocks of C* (5.8),
``sms_cli.formation.decomposition.coriolis``, whose Ṁ* − 2C* is skew) do no work together (C_LE = −C_ELᵀ since
M* stays block-diagonal); they make each subsystem's own W_L or W_E decrease whatever the other does: with the
locked system free and spinning, the shape still converges to its setpoint instead of settling where the
centrifugal coupling balances the spring. The base wrenches are [F1; F2] = Sᵀ[F_L; F_E]; with the locked system free, who applies
F_E is a choice (``actuation``, the thesis's "redistribution", L1068): both bodies (F_L = 0: an internal pair,
total momentum conserved) or one of them (then F_L ≠ 0 and the locked system is pushed).
The free-floating law (5.10) applies no base wrench: the same wheel torques with F = 0. It is a Lyapunov law
when each body's momentum is zero (then V_L = V_E = 0 for ever); the thesis's printed (5.10) drops the Λᵀ
factors (inertia shaping, notes §4.3); this is the unshaped form.
The hierarchical law (§5.4, L1046-L1056; §4.2.4 for one spacecraft) gives the thrusters the same wrenches without
the rotational potentials (the γ terms: they keep the translation springs and damp every momentum) and leaves the
attitude springs to the wheels, whose torques keep the full compensation above; then
Ẇ = −V_LᵀK_LV_L − V_EᵀK_EV_E − K_w|θ̇|² + V_Lᵀ[0; γ_L] + V_Eᵀ([0; γ_E] − A*ᵀ[0; γ_L]): the attitude terms act
through the wheels once the thrusters have taken the momentum out (a task hierarchy, not a strict Lyapunov law;
the wheels' authority scales with Λ, so the attitude gains are those of the free-floating law).
Wheel torques are clipped to each wheel's limit (then Ẇ ≤ 0 is no longer guaranteed; the run counts it).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from sms_cli.formation.decomposition import coriolis, coriolis_blocks


@dataclass
class PoseError:
    """A pose error and its potential: U (J), grad = ∇U (6, body frame, [N; N m]), position error r (m, in the
    setpoint's frame) and rotation angle (rad)."""

    U: float
    grad: np.ndarray
    position: np.ndarray
    angle: float


def pose_potential(g: pin.SE3, g_des: pin.SE3, kp_linear: np.ndarray, kp_angular: np.ndarray) -> PoseError:
    """U, ∇U of the SE(3) potential of the module docstring (γ from the thesis's (4.11), one implementation in
    ``sms_cli.sim.compiled.momentum_laws.trace_potential``)."""
    from sms_cli.sim.compiled.momentum_laws import trace_potential

    R_d, R = g_des.rotation, g.rotation
    r = R_d.T @ (g.translation - g_des.translation)
    R_e = R_d.T @ R
    gamma = np.empty(3)
    phi = trace_potential(np.ascontiguousarray(kp_angular, float), np.ascontiguousarray(R), np.ascontiguousarray(R_d),
                          gamma)
    grad = np.concatenate([R_e.T @ (kp_linear * r), gamma])
    angle = float(np.linalg.norm(pin.log3(R_e)))
    return PoseError(0.5 * float(r @ (kp_linear * r)) + float(phi), grad, r, angle)


def pose_potential_warm_call():
    """``pose_potential``'s kernel call on throw-away arrays of its argument types (``sms_cli.sim.compiled.warmup``)."""
    from sms_cli.sim.compiled.warmup import KernelCall

    return KernelCall("sms_cli.sim.compiled.momentum_laws:trace_potential", (np.ones(3), np.eye(3), np.eye(3), np.empty(3)),
                      cost=0.3)


@dataclass
class Gains:
    """One subsystem's diagonal gains: K_p (3 linear N/m, 3 angular N m/rad) and K_d (6: N s/m, N m s/rad)."""

    controlled: bool
    kp_linear: np.ndarray
    kp_angular: np.ndarray
    kd: np.ndarray

    @classmethod
    def of(cls, spec) -> "Gains":
        return cls(spec.controlled, np.asarray(spec.kp_linear, float), np.asarray(spec.kp_angular, float),
                   np.concatenate([np.asarray(spec.kd_linear, float), np.asarray(spec.kd_angular, float)]))


@dataclass
class Command:
    """What the law applies until the next tick: base wrenches F1, F2 (6 each, own base frame), wheel torques
    (per body), the subsystem wrenches F_L, F_E, the errors and W."""

    F1: np.ndarray
    F2: np.ndarray
    tau_w1: np.ndarray
    tau_w2: np.ndarray
    F_L: np.ndarray
    F_E: np.ndarray
    locked_error: PoseError | None
    shape_error: PoseError | None
    lyapunov: float
    saturated: bool


@dataclass
class BodyState:
    """What the law reads of one body: base pose (world ← base), base twist V (6, base frame), locked twist ξ (6), wheel rates θ̇ (n),
    mechanical connection Λ (6 × n) over its wheels, wheel torque limits (n) and shape inertia of its wheels."""

    pose: pin.SE3
    twist: np.ndarray
    xi: np.ndarray
    wheel_rates: np.ndarray
    connection: np.ndarray
    wheel_limits: np.ndarray
    wheel_inertia: np.ndarray


class RelativeLaw:
    """The free-flying or free-floating relative law of the module docstring."""

    def __init__(self, spec, g1_0: pin.SE3, g12_0: pin.SE3, names: tuple[str, str] = ("master", "other")):
        self.spec = spec
        self.free_flying = spec.relative_law == "free_flying"
        self.hierarchical = spec.relative_law == "hierarchical"
        self.locked = Gains.of(spec.locked)
        self.shape = Gains.of(spec.shape)
        self.wheel_damping = float(spec.wheel_damping)
        by_name = {names[0]: "master", names[1]: "other"}
        self.actuation = by_name.get(spec.actuation, spec.actuation)  # a spacecraft's name → its role
        self.g1_des = g1_0 * spec.locked.setpoint_offset.se3()
        self.g12_des = g12_0 * spec.shape.setpoint_offset.se3()

    def __call__(self, dec, b1: BodyState, b2: BodyState) -> Command:
        V_L, V_E = dec.locked_shape(b1.xi, b2.xi)
        zero = np.zeros(6)
        eL = pose_potential(b1.pose, self.g1_des, self.locked.kp_linear, self.locked.kp_angular) if self.locked.controlled else None
        g12 = b1.pose.actInv(b2.pose)
        eE = pose_potential(g12, self.g12_des, self.shape.kp_linear, self.shape.kp_angular) if self.shape.controlled else None
        gL = eL.grad if eL else zero
        gE = eE.grad if eE else zero
        if self.hierarchical:  # the thrusters keep the translation potentials and all damping; the wheels turn
            gL_f, gE_f = _linear(gL), _linear(gE)
        else:
            gL_f, gE_f = gL, gE
        if self.free_flying or self.hierarchical:
            C = coriolis_blocks(coriolis(dec, b1.xi, b2.xi, b2.twist - dec.Ad12_inv @ b1.twist))
            F_L = -gL_f - self.locked.kd * V_L + C["C_LE"] @ V_E if eL else zero.copy()
            F_E = -gE_f + dec.A_star.T @ gL_f - (self.shape.kd * V_E if eE else 0.0) + (C["C_EL"] @ V_L if eE else 0.0)
            if eL or self.actuation == "both":
                F1, F2 = dec.to_bodies(F_L, F_E)
            else:
                F1, F2 = dec.shape_effort(F_E, self.actuation)
                F_L, F_E = dec.to_locked_shape(F1, F2)
        else:
            F_L, F_E, F1, F2 = zero, zero, zero, zero
        Ad_inv_T_gE = dec.Ad12_inv.T @ gE
        t1 = b1.connection.T @ (F1 + gL - Ad_inv_T_gE) - self.wheel_damping * b1.wheel_rates
        t2 = b2.connection.T @ (F2 + gE) - self.wheel_damping * b2.wheel_rates
        c1, c2 = np.clip(t1, -b1.wheel_limits, b1.wheel_limits), np.clip(t2, -b2.wheel_limits, b2.wheel_limits)
        saturated = bool(np.any(c1 != t1) or np.any(c2 != t2))
        T_L, T_E = dec.energies(V_L, V_E)
        T_w = 0.5 * sum(float(b.wheel_rates @ b.wheel_inertia @ b.wheel_rates) for b in (b1, b2))
        W = T_L + T_E + T_w + (eL.U if eL else 0.0) + (eE.U if eE else 0.0)
        return Command(F1, F2, c1, c2, F_L, F_E, eL, eE, W, saturated)


def _linear(grad: np.ndarray) -> np.ndarray:
    """The translational part of a potential's gradient [f; 0]."""
    return np.concatenate([grad[:3], np.zeros(3)])
