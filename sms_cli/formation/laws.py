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
The per-tick arithmetic is the compiled ``sms_cli.sim.compiled.pair_law.relative_law`` (its one implementation).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from sms_cli.sim.compiled import pair_law as _k


@dataclass
class PoseError:
    """A pose error and its potential: U (J), grad = ∇U (6, body frame, [N; N m]), position error r (m, in the
    setpoint's frame) and rotation angle (rad)."""

    U: float
    grad: np.ndarray
    position: np.ndarray
    angle: float


def _c(x) -> np.ndarray:
    return np.ascontiguousarray(x, dtype=float)


def pose_potential(g: pin.SE3, g_des: pin.SE3, kp_linear: np.ndarray, kp_angular: np.ndarray) -> PoseError:
    """U, ∇U of the SE(3) potential of the module docstring (kernel ``pair_law.pose_error``; γ from the thesis's
    (4.11), ``sms_cli.sim.compiled.momentum_laws.trace_potential``)."""
    grad, r = np.empty(6), np.empty(3)
    U, angle = _k.pose_error(_c(g.rotation), _c(g.translation), _c(g_des.rotation), _c(g_des.translation),
                             _c(kp_linear), _c(kp_angular), grad, r)
    return PoseError(float(U), grad, r, float(angle))


def law_warm_call():
    """``RelativeLaw``'s kernel call on throw-away arrays of its argument types (``sms_cli.sim.compiled.warmup``)."""
    from sms_cli.sim.compiled.warmup import KernelCall

    M, I3, v, z3 = np.eye(6), np.eye(3), np.zeros(6), np.zeros(3)
    wheels = (np.zeros((6, 1)), np.zeros(1), np.ones(1), np.eye(1))
    return KernelCall("sms_cli.sim.compiled.pair_law:relative_law",
                      (_k.FREE_FLYING, _k.BOTH, True, True, np.ones((2, 12)), 0.0, I3, z3, I3, z3, I3, z3, I3, z3,
                       M, M, M, M, M, np.eye(12), np.eye(12), M, v, v, v, v, *wheels, *wheels,
                       np.empty((4, 6)), np.empty(1), np.empty(1), np.empty((2, 8)), np.empty((2, 3))), cost=3.0)


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

        self._mode = _k.HIERARCHICAL if self.hierarchical else _k.FREE_FLYING if self.free_flying else _k.FREE_FLOATING
        self._actuated = {"both": _k.BOTH, "master": _k.MASTER, "other": _k.OTHER}.get(self.actuation, -1)
        self._gains = np.array([np.concatenate([g.kp_linear, g.kp_angular, g.kd]) for g in (self.locked, self.shape)])
        self._setpoints = tuple(_c(x) for g in (self.g1_des, self.g12_des) for x in (g.rotation, g.translation))

    def __call__(self, dec, b1: BodyState, b2: BodyState) -> Command:
        """The command at the decomposition ``dec`` and the bodies' states (kernel ``pair_law.relative_law``)."""
        if self._actuated < 0 and self._mode != _k.FREE_FLOATING and not self.locked.controlled:
            raise ValueError(f"actuated must be 'both', 'master' or 'other', not {self.actuation!r}")
        F = np.empty((4, 6))
        tau1, tau2 = np.empty(b1.wheel_rates.size), np.empty(b2.wheel_rates.size)
        err, pos = np.zeros((2, 8)), np.zeros((2, 3))
        wheels = [(_c(b.connection), _c(b.wheel_rates), _c(b.wheel_limits), _c(b.wheel_inertia)) for b in (b1, b2)]
        W, saturated = _k.relative_law(
            self._mode, self._actuated, self.locked.controlled, self.shape.controlled, self._gains, self.wheel_damping,
            _c(b1.pose.rotation), _c(b1.pose.translation), _c(b2.pose.rotation), _c(b2.pose.translation),
            *self._setpoints, dec.M1, dec.M2, dec.Ad12_inv, dec.M_tot, dec.A_star, dec.S, dec.S_inv, dec.M_E,
            _c(b1.xi), _c(b2.xi), _c(b1.twist), _c(b2.twist), *wheels[0], *wheels[1], F, tau1, tau2, err, pos)
        eL, eE = (PoseError(float(err[i, 0]), err[i, 2:], pos[i], float(err[i, 1])) if g.controlled else None
                  for i, g in enumerate((self.locked, self.shape)))
        return Command(F[0], F[1], tau1, tau2, F[2], F[3], eL, eE, float(W), bool(saturated))
