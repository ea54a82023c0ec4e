"""Kraiem 2022 §3.3–3.4: nonlinear dynamic inversion (NDI) of the actuators' reduced dynamics with a
Luenberger observer of the unmeasured flexible and base states.

Coordinates (SystemModel, augmented velocity x = [v; η̇]): base linear (3), base angular ω0
(3, base frame), actuators a = wheels then arm joints (v-index order), flexible f = spring
joints then modal coordinates η. With u = [base; f] the unactuated coordinates, the equations
M ẍ + r(q, x, f) = [0; τ_a; 0] (r = bias − internal forces) give, eliminating ẍ_u,

    τ_a = M◇ q̈_a + r_a − M_au M_uu⁻¹ r_u,     M◇ = M_aa − M_au M_uu⁻¹ M_ua      (3.33)–(3.35)

so τ_a = M◇ v + n gives q̈_a = v exactly when the state is known. The controller measures the
configuration q, the actuator rates and ω0 (gyro); it estimates x_e = [f; ω0; ḟ] with the
observer (3.31) on the linearisation at rest of ``sms_cli.synthesis.reduced`` (re-evaluated at
the measured configuration every control period, discretised exactly over the period):

    x̂̇ = A_e x̂ + B_τ τ_a + L (ω0 − C_e x̂),     B_τ = [0; −M*⁻¹ M_bq M_qq⁻¹]

and the base linear velocity from zero linear momentum (the Routh reduction the synthesis uses).

Commands v (actuator accelerations, rad/s² or m/s²): arm joints v = q̈_d + kp ε + kv ε̇,
ε = q_d − q (gains from ``gains.yaml`` of ``sms synthesize`` or the mission); wheels hold the base
attitude: ω_des = ω_ref − k_att θ_e (θ_e the rotation vector of q_ref⁻¹ q, base frame), the wheel
rates that move the base rate to ω_des at constant angular momentum, q̇_rd = q̇_r − M_ωr⁺ M_ωω
(ω_des − ω0), and v_r = q̈_rd + kv (q̇_rd − q̇_r), with the feedforward q̈_rd the wheel accelerations
that keep ω̇0 = 0 under the commanded arm acceleration (the derivative of the (3.66) reference;
``wheel_feedforward: false`` leaves it out). Without it the wheel-rate error lags the arm by
|q̈_rd|/kv, and the base attitude error is bounded by a_d/(kv k_att), a_d the peak base angular
acceleration the wheels must cancel (``sms_cli.sim.authority`` reports it per move).
"""

from __future__ import annotations

import numpy as np
import scipy.linalg

from sms_cli.model.system import SystemModel
from sms_cli.sim.attitude_math import attitude_error, quat_conj, quat_mul
from sms_cli.sim.interfaces import ArmRef, AttitudeRef, Sensed
from sms_cli.synthesis.reduced import flexible_stiffness, model_index


class NdiObserver:
    """Combined wheel + arm law: returns actuator torques (wheels first, then arm joints)."""

    def __init__(self, sm: SystemModel, kp: np.ndarray, kv: np.ndarray, L: np.ndarray, attitude_gain: float,
                 period: float, wheel_feedforward: bool = True):
        self.sm = sm
        self.ix, self.names, _ = model_index(sm)
        self.K_f, self.C_f = flexible_stiffness(sm)
        self.n_f = self.K_f.shape[0]
        self.n_r, self.n_m = len(sm.wheels), len(sm.arm)
        self.kp = np.broadcast_to(np.asarray(kp, float), (self.n_r + self.n_m,)).copy()
        self.kv = np.broadcast_to(np.asarray(kv, float), (self.n_r + self.n_m,)).copy()
        self.L = np.asarray(L, float)
        n_e = 2 * self.n_f + 3
        if self.L.shape != (n_e, 3):
            raise ValueError(f"observer gain L must be {n_e}×3 for x = [f; ω0; ḟ], got {self.L.shape}")
        self.k_att = float(attitude_gain)
        self.wheel_feedforward = bool(wheel_feedforward)
        self.T = float(period)
        self.x_hat = np.zeros(n_e)
        self.u = np.concatenate([self.ix.base_linear, self.ix.base_angular, self.ix.flexible])
        self.a = self.ix.actuators
        self.wheel_limit = np.array([w.max_torque for w in sm.wheels])
        self.refresh = 0.01
        a, u, w = self.a, self.u, self.ix.base_angular
        self._ix_au, self._ix_uu, self._ix_ua, self._ix_aa = np.ix_(a, u), np.ix_(u, u), np.ix_(u, a), np.ix_(a, a)
        self._ix_wr, self._ix_ww = np.ix_(w, a[: self.n_r]), np.ix_(w, w)
        self._wheel_pinv = None
        if any(sm.model.parents[wh.joint_id] != sm.base_joint_id for wh in sm.wheels):
            raise ValueError("the NDI law needs the reaction wheels mounted on the base body")
        self._disc = None
        self._disc_q = None
        self._q_act_idx = np.array([a.q_index for a in sm.arm], dtype=int)
        self.saturated = False
        self._started = False
        self.wheel_rate_ref = np.zeros(self.n_r)  # desired wheel rates of the last control period (rad/s)

    def model_changed(self) -> None:
        """A payload was attached or released: the observer's discretisation is rebuilt at the next period."""
        self._disc = None

    def reset(self) -> None:
        self.x_hat[:] = 0.0
        self._started = False
        self._disc = None

    # ------------------------------------------------------------------ estimation
    def _full_velocity(self, M: np.ndarray, s: Sensed) -> np.ndarray:
        """x̂ = [v_lin; ω0; q̇_a; ḟ̂] with v_lin from zero linear momentum."""
        sm, nf = self.sm, self.n_f
        x = np.zeros(sm.nx)
        x[self.ix.base_angular] = s.omega
        x[self.ix.actuators] = s.v[self.ix.actuators]
        x[self.ix.flexible] = self.x_hat[nf + 3:]
        lin = self.ix.base_linear
        x[lin] = -np.linalg.solve(M[np.ix_(lin, lin)], M[lin] @ x)
        return x

    def _observer_step(self, M: np.ndarray, q_act: np.ndarray, y: np.ndarray, tau_a: np.ndarray) -> None:
        """Exact ZOH propagation of the observer over one control period: x̂⁺ = Φ x̂ + Γ (B_τ τ + L y),
        Φ = e^{A_L T}, Γ = ∫₀ᵀ e^{A_L s} ds, A_L = A_e − L C_e. The discretisation is refreshed when the
        actuator configuration has moved by more than ``refresh`` (rad or m) since the last refresh."""
        if self._disc is None or np.max(np.abs(q_act - self._disc_q)) > self.refresh:
            self._disc = self._discretise(M)
            self._disc_q = q_act.copy()
        Phi, Gamma, B_tau = self._disc
        self.x_hat = Phi @ self.x_hat + Gamma @ (B_tau @ tau_a + self.L @ y)

    def _discretise(self, M: np.ndarray):
        from sms_cli.synthesis.reduced import error_model_at_rest

        em = error_model_at_rest(M, self.K_f, self.C_f, self.ix)
        keep = np.concatenate([self.ix.base_angular, self.ix.actuators, self.ix.flexible])
        lin = self.ix.base_linear
        Mk = M[np.ix_(keep, keep)] - M[np.ix_(keep, lin)] @ np.linalg.solve(M[np.ix_(lin, lin)], M[np.ix_(lin, keep)])
        n_w, n_q = 3, len(self.a)
        b = np.concatenate([np.arange(n_w), n_w + n_q + np.arange(self.n_f)])
        q = n_w + np.arange(n_q)
        Mbb, Mbq, Mqq = Mk[np.ix_(b, b)], Mk[np.ix_(b, q)], Mk[np.ix_(q, q)]
        Mstar = Mbb - Mbq @ np.linalg.solve(Mqq, Mbq.T)
        B_tau = np.zeros((len(self.x_hat), n_q))
        B_tau[self.n_f:] = -np.linalg.solve(Mstar, Mbq @ np.linalg.inv(Mqq))
        A_L = em.A_e - self.L @ em.C_e
        lam, V = np.linalg.eig(A_L)
        if np.linalg.cond(V) < 1e8 and np.min(np.abs(lam)) > 1e-12:
            Vi = np.linalg.inv(V)
            e = np.exp(lam * self.T)
            Phi = ((V * e) @ Vi).real
            Gamma = ((V * ((e - 1.0) / lam)) @ Vi).real
        else:  # defective or singular: the augmented-matrix exponential
            n = len(self.x_hat)
            aug = np.zeros((2 * n, 2 * n))
            aug[:n, :n] = A_L
            aug[:n, n:] = np.eye(n)
            E = scipy.linalg.expm(aug * self.T)
            Phi, Gamma = E[:n, :n], E[:n, n:]
        return Phi, Gamma, B_tau

    # ------------------------------------------------------------------ control
    def torques(self, s: Sensed, att_ref: AttitudeRef, arm_ref: ArmRef) -> np.ndarray:
        """Actuator torques (wheels, then arm) for this control period; call ``observe`` afterwards."""
        sm = self.sm
        M = sm.mass_matrix(s.q)
        if not self._started:
            self.x_hat[self.n_f:self.n_f + 3] = s.omega
            self._started = True
        x = self._full_velocity(M, s)
        v_hat, etadot_hat = x[: sm.nv], x[sm.nv:]
        eta_hat = self.x_hat[self.n_f - sm.n_modes:self.n_f] if sm.n_modes else np.zeros(0)
        r = sm.bias_forces(s.q, v_hat, etadot_hat) - sm.internal_forces(s.q, v_hat, eta_hat, etadot_hat)
        # passive spring joints are flexible coordinates: their positions are estimated too
        u, a = self.u, self.a
        Mau = M[self._ix_au]
        sol = np.linalg.solve(M[self._ix_uu], np.column_stack([M[self._ix_ua], r[u]]))
        M_dia = M[self._ix_aa] - Mau @ sol[:, :-1]
        n_term = r[a] - Mau @ sol[:, -1]
        # commands
        v_cmd = np.zeros(len(a))
        if self.n_m:
            q_arm = s.q_arm
            e, ed = arm_ref.q - q_arm, arm_ref.qd - s.qd_arm
            v_cmd[self.n_r:] = arm_ref.qdd + self.kp[self.n_r:] * e + self.kv[self.n_r:] * ed
        if self.n_r:
            theta = attitude_error(att_ref.quat, s.quat)
            R_rb = _rot(quat_mul(quat_conj(s.quat), att_ref.quat))  # base ← reference
            w_des = R_rb @ att_ref.omega - self.k_att * theta
            if self._wheel_pinv is None:  # wheels ride on the base: M_ωr = [I_s a_i] is constant
                self._wheel_pinv = np.linalg.pinv(M[self._ix_wr])
            dq_r = -self._wheel_pinv @ (M[self._ix_ww] @ (w_des - s.omega))
            v_cmd[: self.n_r] = self.kv[: self.n_r] * dq_r
            if self.wheel_feedforward:
                v_cmd[: self.n_r] += self._wheel_feedforward(sol, v_cmd[self.n_r:])
            self.wheel_rate_ref = s.v[a[: self.n_r]] + dq_r  # q̇_rd of the law, for Kraiem 2022 (3.67)
        self._M, self._y, self._q_act = M, s.omega, s.q[self._q_act_idx]
        return self._saturation_aware(M_dia, n_term, v_cmd)

    def _wheel_feedforward(self, sol: np.ndarray, v_arm: np.ndarray) -> np.ndarray:
        """Wheel accelerations q̈_rd that keep the base from rotating (ω̇0 = 0) while the arm accelerates at
        ``v_arm``: the derivative of the wheel-rate reference of Kraiem 2022 (3.66), from the unactuated rows
        ẍ_u = −M_uu⁻¹ (M_ua q̈_a + r_u) (``sol`` = M_uu⁻¹ [M_ua, r_u]), least-norm over the wheels."""
        nr = self.n_r
        w = slice(3, 6)  # u = [base linear, base angular, flexible]
        G = sol[w, :nr]
        return -np.linalg.pinv(G) @ (sol[w, nr:-1] @ v_arm + sol[w, -1])

    def _saturation_aware(self, M_dia: np.ndarray, n_term: np.ndarray, v_cmd: np.ndarray) -> np.ndarray:
        """τ = M◇ v + n, except that wheel torques are first clipped to their limits and the arm torques
        then computed for the wheel accelerations those clipped torques really produce: the arm still
        gets q̈_m = v_m when the wheels saturate (wheel authority is the usual bottleneck)."""
        nr = self.n_r
        tau = M_dia @ v_cmd + n_term
        self.saturated = bool(nr and np.any(np.abs(tau[:nr]) > self.wheel_limit))
        if not self.saturated:
            return tau
        r, m = slice(0, nr), slice(nr, None)
        tau_r = np.clip(tau[:nr], -self.wheel_limit, self.wheel_limit)
        qdd_r = np.linalg.solve(M_dia[r, r], tau_r - M_dia[r, m] @ v_cmd[m] - n_term[r])
        tau[:nr] = tau_r
        tau[m] = M_dia[m, r] @ qdd_r + M_dia[m, m] @ v_cmd[m] + n_term[m]
        return tau

    def observe(self, tau_applied: np.ndarray) -> None:
        """Propagate the observer over the period with the torques actually applied (after saturation)."""
        self._observer_step(self._M, self._q_act, self._y, tau_applied)


def _rot(quat: np.ndarray) -> np.ndarray:
    x, y, z, w = quat
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def build_ndi(spec, sm: SystemModel, period: float, results_dir=None, mission_dir=None) -> NdiObserver:
    """NdiObserver from a mission's ``simulation.ndi`` (and ``gains.yaml`` when gains are not inline)."""
    from pathlib import Path

    from sms_cli.errors import InputError, Problem

    kp, kv, L = spec.kp, spec.kv, spec.L
    if kp is None or kv is None or L is None:
        from sms_cli.synthesis.gains_io import read_gains

        candidates = [Path(mission_dir) / spec.gains] if spec.gains and mission_dir else []
        candidates += [Path(results_dir) / (spec.gains or "gains.yaml")] if results_dir else []
        path = next((c for c in candidates if c.exists()), None)
        if path is None:
            raise InputError(problems=[Problem(
                "simulation.ndi needs gains: none given and no gains.yaml found "
                f"({', '.join(str(c) for c in candidates) or 'no results folder'})", field="simulation.ndi",
                hint="run `sms synthesize` on this mission first (same --out), or give kp, kv and L")])
        g = read_gains(path)
        if g.controller is None or g.observer is None:
            raise InputError(problems=[Problem(f"{path}: the NDI needs controller and observer gains (law lmi)",
                                               hint="synthesize with synthesis.law: lmi")])
        names = [w.name for w in sm.wheels] + [a.name for a in sm.arm]
        if list(g.actuators) != names:
            raise InputError(problems=[Problem(f"{path}: gains are for actuators {g.actuators}, the model has {names}",
                                               hint="re-run sms synthesize for this mission")])
        if g.controller.units != "acceleration":
            raise InputError(problems=[Problem(f"{path}: NDI gains must be in 'acceleration' units")])
        kp = kp if kp is not None else g.controller.kp
        kv = kv if kv is not None else g.controller.kv
        L = L if L is not None else g.observer.L
    try:
        return NdiObserver(sm, np.asarray(kp, float), np.asarray(kv, float), np.asarray(L, float),
                           spec.attitude_gain, period, spec.wheel_feedforward)
    except ValueError as exc:
        raise InputError(problems=[Problem(str(exc), field="simulation.ndi")]) from None
