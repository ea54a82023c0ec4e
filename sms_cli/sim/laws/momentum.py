"""Momentum-based attitude laws of Vicariotto 2023 ch. 4, each with its Lyapunov function W (issue #12 item 3).

Unlike the laws of ``attitude`` (a base torque the engine allocates to the wheels or the thrusters), these
laws return what they actuate: ``actuate(sensed, ref) -> (wheel torques (n_w,) or None, base wrench (6,) or
None)``, the wrench in Pinocchio's base joint frame ``[f; n]`` about the base origin (the thrusters' input).
``lyapunov_terms(q, v, ref_quat) -> dict`` evaluates the law's W and its terms on a state (recorded on
``/control/lyapunov``).

Quantities (base frame, SI; ``sms_cli.dynamics.locked``, Vicariotto 2023 (4.2)-(4.8)): I the locked inertia
about the CoM, G J the wheel coupling, Λ = I⁻¹GJ, μ = ω + Λθ̇, M_θ = J − JGᵀI⁻¹GJ (the wheels' shape inertia).
Attitude error (Vicariotto 2023 L361): R_e = R_dᵀR, R (world ← base) the base attitude and R_d (world ←
reference) the phase's reference, held constant (regulation, the thesis's case; a slewing reference is not
covered by the proofs). Potential Φ = ½ tr(K_p(1 − R_e)) (L375) with K_p = diag(kp), γ = (skew(K_p R_e))^∨
(4.11, L718), so that Φ̇ = γᵀω.

Exact dynamics used by the proofs (derived here from the mass matrix blocks, any wheel axes G; the thesis's
(4.6)/(4.7) with its errata, notes §9 items 12 and 18):

- locked: I μ̇ + ω × (Iμ) = τ_c (external torque about the CoM), so d/dt ½μᵀIμ = μᵀτ_c + μᵀ((Λθ̇) × Iμ);
- shape: τ_w = J(Gᵀω̇ + θ̈) gives M_θ θ̈ = τ_w − Λᵀτ_c + Λᵀ(ω × Iμ).

Shaped wheel kinetic energy ½θ̇ᵀXθ̇: X = M_θ (plain) or X = ΛᵀM_θ (inertia shaping, §4.2.2, (4.14); needs
3 wheels and ΛᵀM_θ symmetric positive definite, true for A = I as in the thesis). The wheel law
τ_w = M_θX⁻¹(Λᵀγ − K_dθ̇) gives d/dt(½θ̇ᵀXθ̇ + Φ) = −θ̇ᵀK_dθ̇ at μ = 0: with X = M_θ it is (4.13) exactly,
τ_w = Λᵀγ − K_dθ̇; with X = ΛᵀM_θ and A = I it is τ_w = γ − Λ⁻ᵀK_dθ̇, the notes' reading (§4.3) of the garbled
L772-L776 law "τ_w = γ − K_dθ̇" (the stiffness enters without the Λᵀ factor, the rotors behave as if their
inertia were ΛᵀM_θ), with the damping written so that Ẇ_θ = −θ̇ᵀK_dθ̇ as the thesis prints.
"""

from __future__ import annotations

import numpy as np

from sms_cli.sim.attitude_math import quat_conj, quat_mul
from sms_cli.sim.interfaces import AttitudeRef, Sensed

ANG = slice(3, 6)


def quat_to_rot(q) -> np.ndarray:
    """Rotation matrix of a unit quaternion [x, y, z, w] (Hamilton)."""
    x, y, z, w = (float(c) for c in q)
    n = x * x + y * y + z * z + w * w
    s = 2.0 / n
    return np.array([[1 - s * (y * y + z * z), s * (x * y - z * w), s * (x * z + y * w)],
                     [s * (x * y + z * w), 1 - s * (x * x + z * z), s * (y * z - x * w)],
                     [s * (x * z - y * w), s * (y * z + x * w), 1 - s * (x * x + y * y)]])


def potential(Kp: np.ndarray, R: np.ndarray, Rd: np.ndarray) -> tuple[float, np.ndarray]:
    """(Φ, γ): Φ = ½ tr(K_p(1 − R_e)), γ = (skew(K_p R_e))^∨, R_e = R_dᵀR (Vicariotto 2023 L361, L375, (4.11))."""
    Re = Rd.T @ R
    A = Kp @ Re
    S = 0.5 * (A - A.T)
    return 0.5 * float(np.trace(Kp - A)), np.array([S[2, 1], S[0, 2], S[1, 0]])


def _diag(x, n: int, name: str) -> np.ndarray:
    a = np.asarray(x, float)
    a = np.full(n, float(a)) if a.ndim == 0 else a
    if a.shape != (n,) or not np.all(a > 0):
        raise ValueError(f"{name}: one positive value or {n}")
    return np.diag(a)


class _MomentumLaw:
    """Common part: the locked/shape quantities (cached on a wheel-only rigid robot; recomputed per call when
    the mass changes, i.e. with real thrusters and propellant) and the attitude potential."""

    uses_wrench = False
    needs_wheels = True

    def __init__(self, sm, kp, shaping: bool):
        from sms_cli.dynamics.locked import locked_shape, shape_invariant

        if not sm.wheels and self.needs_wheels:
            raise ValueError("this law needs reaction wheels")
        if not shape_invariant(sm):
            raise ValueError("this law needs a rigid base whose only other joints are balanced wheels (no arm, no modes): "
                             "its Λ, I and M_θ are taken constant along the motion")
        self.sm = sm
        self.Kp = _diag(kp, 3, "kp")
        self.shaping = shaping
        self._fixed_mass = sm.thrusters is None
        self._ls = locked_shape(sm, sm.q0) if self._fixed_mass else None
        self._locked_shape = locked_shape
        ls = self._quantities(sm.q0)
        if shaping:
            if ls.Lambda.shape[1] != 3:
                raise ValueError("inertia shaping (Vicariotto 2023 §4.2.2) needs 3 wheels: X = ΛᵀM_θ is n×n only for n = 3")
            X = ls.Lambda.T @ ls.M_theta
            if np.abs(X - X.T).max() > 1e-9 * np.abs(X).max() or np.linalg.eigvalsh(0.5 * (X + X.T)).min() <= 0:
                raise ValueError("inertia shaping needs ΛᵀM_θ symmetric positive definite (wheel axes along the locked "
                                 "inertia's principal axes, as A = I in Vicariotto 2023 L762)")

    def _quantities(self, q):
        if self._fixed_mass:
            return self._ls
        return self._locked_shape(self.sm, q, self.sm.rigid_mass_matrix(q))

    def locked_velocity(self, q, v) -> np.ndarray:
        """μ (3,) rad/s, base frame, from the law's locked/shape quantities (cached while the mass is fixed)."""
        return self._quantities(q).locked_velocity(np.asarray(v, float))

    def _X(self, ls) -> np.ndarray:
        if not self.shaping:
            return ls.M_theta
        X = ls.Lambda.T @ ls.M_theta
        return 0.5 * (X + X.T)

    def _state(self, q, v, ref_quat):
        ls = self._quantities(q)
        v = np.asarray(v, float)
        wd = v[self.sm.idx.wheels]
        mu = ls.locked_velocity(v)
        phi, gamma = self._potential(q, ref_quat)
        return ls, v, wd, mu, phi, gamma

    def _potential(self, q, ref_quat) -> tuple[float, np.ndarray]:
        """(Φ, γ) with Φ̇ = γᵀω: the trace potential ½tr(K_p(1 − R_e)) of (4.11)."""
        return potential(self.Kp, quat_to_rot(q[3:7]), quat_to_rot(ref_quat))

    def _wheel_law(self, ls, gamma, wd, Kd) -> np.ndarray:
        """M_θX⁻¹(Λᵀγ − K_dθ̇): (4.13) for X = M_θ, (4.18)/§4.2.2 for X = ΛᵀM_θ."""
        u = ls.Lambda.T @ gamma - Kd @ wd
        return u if not self.shaping else ls.M_theta @ np.linalg.solve(self._X(ls), u)

    def _terms(self, ls, mu, wd, phi) -> dict:
        return {"locked": 0.5 * float(mu @ ls.I @ mu), "shape": 0.5 * float(wd @ self._X(ls) @ wd), "potential": phi}

    def reset(self) -> None:
        pass


class WheelsFreeFloating(_MomentumLaw):
    """Free-floating, wheels only (Vicariotto 2023 (4.13), L737): τ_w = Λᵀγ − K_dθ̇; with inertia shaping
    (§4.2.2, L762-L780) τ_w = M_θ(ΛᵀM_θ)⁻¹(Λᵀγ − K_dθ̇) (= γ − Λ⁻ᵀK_dθ̇ for A = I). No base wrench.

    W (4.9) = ½μᵀIμ + ½θ̇ᵀM_θθ̇ + Φ (plain), W_θ (L768) = ½θ̇ᵀΛᵀM_θθ̇ + Φ (shaped; ½μᵀIμ is reported as a term).
    At zero momentum (μ = 0, no external torque) Ẇ = −θ̇ᵀK_dθ̇ (L741, L780)."""

    def __init__(self, sm, kp, kd, inertia_shaping: bool = False):
        super().__init__(sm, kp, inertia_shaping)
        self.Kd = _diag(kd, len(sm.wheels), "kd")

    def actuate(self, s: Sensed, ref: AttitudeRef):
        ls, v, wd, mu, phi, gamma = self._state(s.q, s.v, ref.quat)
        return self._wheel_law(ls, gamma, wd, self.Kd), None

    def lyapunov_terms(self, q, v, ref_quat) -> dict:
        ls, v, wd, mu, phi, gamma = self._state(q, v, ref_quat)
        d = self._terms(ls, mu, wd, phi)
        d["W"] = d["shape"] + d["potential"] + (0.0 if self.shaping else d["locked"])
        d["dissipation"] = float(wd @ self.Kd @ wd)  # −Ẇ of the proof
        return d


class FreeFlying(_MomentumLaw):
    """Free-flying, thrusters + wheels (Vicariotto 2023 (4.15)/(4.16), L793-L801), translation PD (3.7):

    τ_c = −γ − K_d^b μ + (Iμ) × (Λθ̇)                         (4.15: the torque about the CoM)
    τ_w = Λᵀτ_c + M_θX⁻¹(Λᵀγ − K_d^w θ̇) − Λᵀ(ω × Iμ)          (4.16: the Coriolis coupling cancelled)
    f   = Rᵀ(−K_p^x Δx − K_d^x ċ)                             ((3.7) in the world frame, rotated into the base
                                                                frame: erratum 3 of the notes, L351 vs (3.13))

    Δx = c − c_d, c the system CoM (world), c_d its value at the first control tick (or ``target_com``); the
    wrench about the base origin is [f; τ_c + c_b × f] (c_b the CoM in the base frame). X = ΛᵀM_θ (inertia-
    shaped rotors, "considering the shaped-inertia kinetic energy", L791) or M_θ.
    W = ½m|ċ|² + ½ΔxᵀK_p^xΔx + ½μᵀIμ + ½θ̇ᵀXθ̇ + Φ, Ẇ = −ċᵀK_d^xċ − μᵀK_d^bμ − θ̇ᵀK_d^wθ̇ (4.17)."""

    uses_wrench = True

    def __init__(self, sm, kp, kd_base, kd_wheels, inertia_shaping: bool = True, kp_position=None,
                 kd_position=None, target_com=None):
        super().__init__(sm, kp, inertia_shaping)
        self.Kb = _diag(kd_base, 3, "kd_base")
        self.Kw = _diag(kd_wheels, len(sm.wheels), "kd_wheels")
        self._init_translation(kp_position, kd_position, target_com)

    def _init_translation(self, kp_position, kd_position, target_com) -> None:
        """The translation PD (3.7) on the CoM: gains (N/m, N s/m) and target (world, m; none: the CoM at
        the first tick)."""
        self.translate = kp_position is not None
        self.Kx = _diag(kp_position, 3, "kp_position") if self.translate else None
        self.Dx = _diag(kd_position, 3, "kd_position") if self.translate else None
        self.target = None if target_com is None else np.asarray(target_com, float)
        self._target0 = self.target

    def reset(self) -> None:
        self.target = self._target0

    def _com(self, ls, q, v):
        R = quat_to_rot(q[3:7])
        c = np.asarray(q[:3], float) + R @ ls.com_base
        cdot = R @ (v[:3] + ls.T[0:3, 3:] @ v[3:])  # v_c = v + M_vv⁻¹[M_vω, M_vs] ẋ (locked.py's T), world
        return R, c, cdot

    def _wrench(self, ls, q, v, tau_c) -> np.ndarray:
        """Base wrench [f; n] (base frame, about the base origin) of the CoM torque ``tau_c`` and the
        translation PD (3.7) rotated into the base frame (erratum 3): f = Rᵀ(−K_p^xΔx − K_d^xċ)."""
        f = np.zeros(3)
        if self.translate:
            R, c, cdot = self._com(ls, q, v)
            if self.target is None:
                self.target = c.copy()
            f = R.T @ (-self.Kx @ (c - self.target) - self.Dx @ cdot)
        return np.concatenate([f, tau_c + np.cross(ls.com_base, f)])

    def _translation_terms(self, d: dict, ls, q, v) -> float:
        """Put the translation's part of W, ½m|ċ|² + ½ΔxᵀK_p^xΔx, in ``d["translation"]`` (and the CoM's distance
        to its target |Δx|, m, in ``d["position_error"]`` when the PD acts); return its dissipation ċᵀK_d^xċ."""
        d["translation"] = 0.0
        if not self.translate:
            return 0.0
        R, c, cdot = self._com(ls, q, v)
        dx = c - (c if self.target is None else self.target)
        d["translation"] = 0.5 * ls.mass * float(cdot @ cdot) + 0.5 * float(dx @ self.Kx @ dx)
        d["position_error"] = float(np.linalg.norm(dx))
        return float(cdot @ self.Dx @ cdot)

    def actuate(self, s: Sensed, ref: AttitudeRef):
        ls, v, wd, mu, phi, gamma = self._state(s.q, s.v, ref.quat)
        Imu = ls.I @ mu
        omega = v[ANG]
        tau_c = -gamma - self.Kb @ mu + np.cross(Imu, ls.Lambda @ wd)
        tau_w = ls.Lambda.T @ tau_c + self._wheel_law(ls, gamma, wd, self.Kw) - ls.Lambda.T @ np.cross(omega, Imu)
        return tau_w, self._wrench(ls, s.q, v, tau_c)

    def lyapunov_terms(self, q, v, ref_quat) -> dict:
        ls, v, wd, mu, phi, gamma = self._state(q, v, ref_quat)
        d = self._terms(ls, mu, wd, phi)
        diss = self._translation_terms(d, ls, q, v)
        diss += float(mu @ self.Kb @ mu + wd @ self.Kw @ wd)
        d["W"] = d["locked"] + d["shape"] + d["potential"] + d["translation"]
        d["dissipation"] = diss
        return d


class Hierarchical(_MomentumLaw):
    """Hierarchical (Vicariotto 2023 §4.2.4, L814-L840): task 1, the thrusters detumble the locked motion,
    τ_c = −K_d^b μ + (Iμ) × (Λθ̇) (L826; wheels idle), W_1 = ½μᵀIμ, Ẇ_1 = −μᵀK_d^bμ; once |μ| ≤
    ``mu_threshold`` (rad/s; the thesis gives none, "once the cancellation of any residual momentum is
    accomplished", L814) task 2 for the rest of the run (latched): no wrench, the wheels' inertia-shaped law
    (4.18) τ_w = M_θX⁻¹(Λᵀγ − K_d^wθ̇), W_2 = ½θ̇ᵀXθ̇ + Φ (L830). W_2's proof assumes μ = 0; the residual μ
    left by the threshold adds the power ``residual`` = γᵀμ + θ̇ᵀXM_θ⁻¹Λᵀ(ω × Iμ) to Ẇ_2 = −θ̇ᵀK_d^wθ̇."""

    uses_wrench = True

    def __init__(self, sm, kp, kd_base, kd_wheels, mu_threshold: float, inertia_shaping: bool = True):
        super().__init__(sm, kp, inertia_shaping)
        self.Kb = _diag(kd_base, 3, "kd_base")
        self.Kw = _diag(kd_wheels, len(sm.wheels), "kd_wheels")
        self.threshold = float(mu_threshold)
        self.stage = 1

    def reset(self) -> None:
        self.stage = 1

    def actuate(self, s: Sensed, ref: AttitudeRef):
        ls, v, wd, mu, phi, gamma = self._state(s.q, s.v, ref.quat)
        if self.stage == 1 and float(np.linalg.norm(mu)) <= self.threshold:
            self.stage = 2
        if self.stage == 1:
            tau_c = -self.Kb @ mu + np.cross(ls.I @ mu, ls.Lambda @ wd)
            return np.zeros(len(wd)), np.concatenate([np.zeros(3), tau_c])
        return self._wheel_law(ls, gamma, wd, self.Kw), np.zeros(6)

    def lyapunov_terms(self, q, v, ref_quat) -> dict:
        ls, v, wd, mu, phi, gamma = self._state(q, v, ref_quat)
        d = self._terms(ls, mu, wd, phi)
        d["stage"] = float(self.stage)
        if self.stage == 1:
            d["W"] = d["locked"]
            d["dissipation"] = float(mu @ self.Kb @ mu)
            d["residual"] = 0.0
        else:
            d["W"] = d["shape"] + d["potential"]
            d["dissipation"] = float(wd @ self.Kw @ wd)
            X = self._X(ls)
            cor = ls.Lambda.T @ np.cross(v[ANG], ls.I @ mu)
            d["residual"] = float(gamma @ mu + wd @ X @ np.linalg.solve(ls.M_theta, cor))
        return d


class Se3PD(FreeFlying):
    """Bullo-Murray PD on SE(3) (Vicariotto 2023 (3.7), (3.9), L351, L385) with the thrusters (or the ideal
    source), the wheels idle (zero torque): τ_c = −γ − K_dω about the CoM (erratum 4: (3.9) read as
    u_t = −γ − K_dω_b), f = Rᵀ(−K_p^xΔx − K_d^xċ) ((3.7) rotated into the base frame, erratum 3).
    W (L449) = ½m|ċ|² + ½ωᵀ(I − GJGᵀ)ω + ½ΔxᵀK_p^xΔx + Φ: the rigid body's, with I − GJGᵀ the inertia
    without the rotors' axial parts (idle rotors keep their axial momentum J(Gᵀω + θ̇), whose energy is
    constant), so that Ẇ = −ċᵀK_d^xċ − ωᵀK_dω ((3.15); = L449 exactly without wheels)."""

    needs_wheels = False

    def __init__(self, sm, kp, kd, kp_position=None, kd_position=None, target_com=None):
        _MomentumLaw.__init__(self, sm, kp, False)
        self.Kd = _diag(kd, 3, "kd")
        self._init_translation(kp_position, kd_position, target_com)

    def actuate(self, s: Sensed, ref: AttitudeRef):
        ls, v, wd, mu, phi, gamma = self._state(s.q, s.v, ref.quat)
        tau_c = -gamma - self.Kd @ v[ANG]
        return np.zeros(len(wd)), self._wrench(ls, s.q, v, tau_c)

    def lyapunov_terms(self, q, v, ref_quat) -> dict:
        ls, v, wd, mu, phi, gamma = self._state(q, v, ref_quat)
        w = v[ANG]
        Ib = ls.I - (ls.G * ls.J) @ ls.G.T
        d = {"rotation": 0.5 * float(w @ Ib @ w), "potential": phi}
        diss = self._translation_terms(d, ls, q, v)
        diss += float(w @ self.Kd @ w)
        d["W"] = d["rotation"] + d["potential"] + d["translation"]
        d["dissipation"] = diss
        return d


class QuaternionLyapunov(Se3PD):
    """The quaternion PD of Vicariotto 2023 §3.3.1 (L417-L435) with its Lyapunov function, on the base
    (thrusters or the ideal source; wheels idle; optional translation PD (3.7) as ``se3_pd``):
    τ_c = −k q₀ q − K_dω, (q₀, q) the error quaternion q_ref⁻¹ ⊗ q (scalar part q₀, vector part q, body
    frame), W = ½ωᵀ(I − GJGᵀ)ω + k qᵀq (+ the translation terms), Ẇ = −ωᵀK_dω: since
    q̇ = ½(q₀ω + q × ω), d/dt(k qᵀq) = k q₀ qᵀω, so the potential's γ is k q₀ q. k is one number (a diagonal
    K would leave qᵀK(q × ω) ≠ 0). ``quaternion_pd`` is L443's alternative τ = −k q_e − K_dω, without this W."""

    def __init__(self, sm, k, kd, kp_position=None, kd_position=None, target_com=None):
        super().__init__(sm, np.full(3, float(k)), kd, kp_position, kd_position, target_com)
        self.k = float(k)

    def _potential(self, q, ref_quat) -> tuple[float, np.ndarray]:
        qe = quat_mul(quat_conj(np.asarray(ref_quat, float)), np.asarray(q[3:7], float))
        qv, q0 = qe[:3], float(qe[3])
        return self.k * float(qv @ qv), self.k * q0 * qv
