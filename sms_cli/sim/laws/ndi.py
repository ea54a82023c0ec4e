"""Kraiem 2022 §3.3–3.4: nonlinear dynamic inversion (NDI) of the actuators' reduced dynamics with a
Luenberger observer of the unmeasured flexible and base states.

Coordinates (SystemModel, augmented velocity x = [v; η̇]): base linear (3), base angular ω0
(3, base frame), actuators a = wheels then arm joints (v-index order), flexible f = spring
joints then modal coordinates η. With u = [base; f] the unactuated coordinates, the equations
M ẍ + r(q, x, f) = [0; τ_a; 0] (r = bias − internal forces) give, eliminating ẍ_u,

    τ_a = M◇ q̈_a + r_a − M_au M_uu⁻¹ r_u,     M◇ = M_aa − M_au M_uu⁻¹ M_ua      (3.33)–(3.35)

so τ_a = M◇ v + n gives q̈_a = v exactly when the state is known. The controller measures the
configuration q, the actuator rates and ω0 (gyro); it estimates x_e = [f; ω0; ḟ] with the
observer (3.31) on the linearisation at rest of ``sms_cli.model.reduced`` (re-evaluated at
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

from sms_cli.model.system import SystemModel
from sms_cli.sim.interfaces import ArmRef, AttitudeRef, Sensed


def _f64(x) -> np.ndarray:
    return np.ascontiguousarray(x, dtype=float)


class NdiObserver:
    """Combined wheel + arm law: returns actuator torques (wheels first, then arm joints). The arithmetic is
    ``sms_cli.sim.compiled.ndi_law`` (the one implementation, which the compiled loop calls too); this
    class holds the law's state and evaluates M and the bias forces with the SystemModel (Pinocchio) ``sm``: the
    plant's, or a copy with model errors (``sms_cli.model.model_errors``; then ``model_changed`` follows the plant's
    payloads on it)."""

    def __init__(self, sm: SystemModel, kp: np.ndarray, kv: np.ndarray, L: np.ndarray, attitude_gain: float,
                 period: float, wheel_feedforward: bool = True, Q_d: np.ndarray | None = None):
        from sms_cli.sim.compiled.ndi_law import N_FLAGS

        self.sm = sm
        red = sm.reduced
        self.ix, self.names = red.ix, red.actuator_names
        self.K_f, self.C_f = red.K_f, red.C_f
        self.n_f = self.K_f.shape[0]
        self.n_r, self.n_m = len(sm.wheels), len(sm.arm)
        self.kp = np.broadcast_to(np.asarray(kp, float), (self.n_r + self.n_m,)).copy()
        self.kv = np.broadcast_to(np.asarray(kv, float), (self.n_r + self.n_m,)).copy()
        self.L = np.ascontiguousarray(L, dtype=float)
        n_e = 2 * self.n_f + 3
        if self.L.shape != (n_e, 3):
            raise ValueError(f"observer gain L must be {n_e}×3 for x = [f; ω0; ḟ], got {self.L.shape}")
        self.k_att = float(attitude_gain)
        self.wheel_feedforward = bool(wheel_feedforward)
        self.T = float(period)
        self.x_hat = np.zeros(n_e)
        self.a = self.ix.actuators
        self.wheel_limit = np.array([w.max_torque for w in sm.wheels], dtype=float)
        self.refresh = 0.01
        if any(sm.model.parents[wh.joint_id] != sm.base_joint_id for wh in sm.wheels):
            raise ValueError("the NDI law needs the reaction wheels mounted on the base body")
        n_q = self.n_r + self.n_m
        self.flags = np.zeros(N_FLAGS, dtype=np.int64)  # ndi_law.STARTED, DISC_VALID, PINV_VALID, SATURATED
        self.wheel_pinv = np.zeros((self.n_r, 3))
        self.disc_q = np.zeros(self.n_m)
        self.Phi, self.Gamma, self.B_tau = np.zeros((n_e, n_e)), np.zeros((n_e, n_e)), np.zeros((n_e, n_q))
        self._q_act_idx = np.array([a.q_index for a in sm.arm], dtype=int)
        self.wheel_rate_ref = np.zeros(self.n_r)  # desired wheel rates of the last control period (rad/s)
        self._x = np.zeros(sm.nx)
        self._tau = np.zeros(n_q)
        # disturbance observer (Kraiem 2022 ch. 4): on when Q_d is given; τ̂_d and its discretisation
        self.ndo = Q_d is not None
        self.Q_d = np.zeros((n_q, n_q)) if Q_d is None else np.ascontiguousarray(Q_d, dtype=float)
        if self.Q_d.shape != (n_q, n_q):
            raise ValueError(f"the disturbance observer's Q_d must be {n_q}×{n_q} (wheels, then arm), got {self.Q_d.shape}")
        self.ndo_Phi, self.ndo_H = np.zeros((n_q, n_q)), np.zeros((n_q, n_q))
        self.ndo_g, self.tau_hat = np.zeros(n_q), np.zeros(n_q)
        self.plant: SystemModel | None = None  # the plant's model when ``sm`` is a copy with model errors
        # the last command's feedback, linearising and disturbance parts (3 × n_q; ndi_law.torque_split)
        self.split = np.zeros((3, n_q))
        self._x_lin = np.zeros(sm.nx)
        self._model_arrays = None

    @property
    def saturated(self) -> bool:
        """The last period's wheel torques exceeded their limits (the arm torques were recomputed)."""
        from sms_cli.sim.compiled.ndi_law import SATURATED

        return bool(self.flags[SATURATED])

    @property
    def has_model_errors(self) -> bool:
        """The law's model is not the plant's (``simulation.ndi.model_errors``)."""
        return self.plant is not None

    def model_changed(self, plant: SystemModel | None = None) -> None:
        """A payload was attached or released on ``plant``: the law's own model follows it (model errors), and
        the observer's discretisation is rebuilt at the next period."""
        from sms_cli.model.model_errors import follow_payloads
        from sms_cli.sim.compiled.ndi_law import DISC_VALID

        if self.has_model_errors and plant is not None:
            follow_payloads(self.sm, plant)
            self._model_arrays = None
        self.flags[DISC_VALID] = 0

    def model_arrays(self) -> tuple:
        """The law's model as the compiled loop takes it (with model errors): the flattened tree's body inertias,
        then B, −Ω², −2ζΩ of the base-mounted modes (``compiled.plant.modal_arrays``)."""
        if self._model_arrays is None:
            from sms_cli.sim.compiled.plant import modal_arrays
            from sms_cli.sim.compiled.tree import flatten

            B, _, _, no2, n2z = modal_arrays(self.sm)
            self._model_arrays = (flatten(self.sm.model).inertia, B, no2, n2z)
        return self._model_arrays

    def reset(self) -> None:
        self.x_hat[:] = 0.0
        self.tau_hat[:] = 0.0
        self.split[:] = 0.0
        self.flags[:] = 0

    def kernel_args(self) -> tuple:
        """The law's constants and state as ``ndi_law``'s kernels take them (the compiled loop's arguments):
        index sets, gains, K_f, C_f, L, period, refresh, the state arrays (updated in place), then the disturbance
        observer: on, Q_d and its state."""
        ix = self.ix
        return (ix.base_linear, ix.base_angular, ix.actuators, ix.flexible, self.n_r, self.kp, self.kv, self.k_att,
                self.wheel_feedforward, self.wheel_limit, _f64(self.K_f), _f64(self.C_f), self.L, self.T,
                float(self.refresh), self.flags, self.wheel_pinv, self.wheel_rate_ref, self.disc_q, self.Phi, self.Gamma,
                self.B_tau, self.x_hat, self.ndo, self.Q_d, self.ndo_Phi, self.ndo_g, self.ndo_H, self.tau_hat)

    # ------------------------------------------------------------------ control
    def torques(self, s: Sensed, att_ref: AttitudeRef, arm_ref: ArmRef) -> np.ndarray:
        """Actuator torques (wheels, then arm) for this control period; call ``observe`` afterwards."""
        from sms_cli.sim.compiled.ndi_law import (actuator_dynamics, ndi_command, ndi_velocity, ndo_estimate, reduced_bias,
                                                  rigid_velocity, torque_split)

        sm, ix = self.sm, self.ix
        M = _f64(sm.mass_matrix(s.q))
        omega, v = _f64(s.omega), _f64(s.v)
        ndi_velocity(M, ix.base_linear, ix.base_angular, ix.actuators, ix.flexible, omega, v, self.x_hat, self.flags,
                     self._x)
        x = self._x
        v_hat, etadot_hat = x[: sm.nv], x[sm.nv:]
        eta_hat = self.x_hat[self.n_f - sm.n_modes:self.n_f] if sm.n_modes else np.zeros(0)
        # passive spring joints are flexible coordinates: their positions are estimated too
        r = _f64(sm.bias_forces(s.q, v_hat, etadot_hat) - sm.internal_forces(s.q, v_hat, eta_hat, etadot_hat))
        M_dia, n_term, sol = actuator_dynamics(M, r, ix.base_linear, ix.base_angular, ix.actuators, ix.flexible)
        n_cmd = n_term
        if self.ndo:  # τ = M◇ v + n − τ̂_d (Kraiem 2022 (4.21))
            ndo_estimate(_f64(v[ix.actuators]), self.flags, self.ndo_Phi, self.ndo_g, self.ndo_H, self.tau_hat)
            n_cmd = n_term - self.tau_hat
        ndi_command(M, M_dia, n_cmd, sol, ix.base_angular, ix.actuators, self.n_r, self.kp, self.kv,
                    self.k_att, self.wheel_feedforward, self.wheel_limit, _f64(s.quat), omega, v, _f64(s.q_arm),
                    _f64(att_ref.quat), _f64(att_ref.omega), _f64(arm_ref.q), _f64(arm_ref.qd), _f64(arm_ref.qdd),
                    self.flags, self.wheel_pinv, self.wheel_rate_ref, self._tau)
        rigid_velocity(M, ix.base_linear, ix.base_angular, ix.actuators, ix.flexible, v, self._x_lin)
        v_lin, zero = self._x_lin[: sm.nv], np.zeros(sm.n_modes)
        r_lin = _f64(sm.bias_forces(s.q, v_lin, zero) - sm.internal_forces(s.q, v_lin, zero, zero))
        n_lin = reduced_bias(sol, r_lin, ix.base_linear, ix.base_angular, ix.actuators, ix.flexible)
        torque_split(n_term, n_lin, self.tau_hat, self.ndo, self._tau, self.split)
        self._M, self._y, self._q_act, self._qdot_a = M, omega, _f64(s.q[self._q_act_idx]), _f64(v[ix.actuators])
        self._M_dia, self._n_term = M_dia, n_term
        return self._tau.copy()

    def observe(self, tau_applied: np.ndarray) -> None:
        """Propagate the observer over the period with the torques actually applied (after saturation)."""
        from sms_cli.sim.compiled.ndi_law import ndi_observe, ndo_refresh

        ix = self.ix
        ndi_observe(self._M, self._q_act, self._y, _f64(tau_applied), ix.base_linear, ix.base_angular, ix.actuators,
                    ix.flexible, _f64(self.K_f), _f64(self.C_f), self.L, self.T, float(self.refresh), self.flags,
                    self.disc_q, self.Phi, self.Gamma, self.B_tau, self.x_hat)
        if self.ndo:
            ndo_refresh(self._M_dia, self._n_term, self._qdot_a, _f64(tau_applied), self.Q_d, self.T, self.flags,
                        self.ndo_Phi, self.ndo_g, self.ndo_H)

    def warm_calls(self) -> list:
        """The kernel calls of ``torques`` and ``observe`` on throw-away data (``sms_cli.sim.compiled.warmup``)."""
        return ndi_warm_calls(self)


def ndi_warm_calls(law: NdiObserver) -> list:
    """``ndi_law``'s kernels with the argument types of their calls (both loops), on copies of the law's state."""
    from sms_cli.sim.compiled.warmup import KernelCall

    sm = law.sm
    (lin, ang, act, flex, n_r, kp, kv, k_att, ff, wl, K_f, C_f, L, T, refresh, flags, pinv, wrr, dq, Phi, Gam, Bt,
     xh, _, Q_d, nPhi, ng, nH, th) = law.kernel_args()
    M = np.eye(sm.nx)
    z = lambda n: np.zeros(n)  # noqa: E731
    n_q, n_e = act.size, xh.size
    sol = np.zeros((sm.nx - n_q, n_q + 1), order="F")  # actuator_dynamics' M_uu⁻¹ [M_ua, r_u]: numba's solve is F-ordered
    mod = "sms_cli.sim.compiled.ndi_law"
    return [
        KernelCall(f"{mod}:ndi_velocity", (M, lin, ang, act, flex, z(3), z(sm.nv), xh.copy(), flags.copy(), z(sm.nx)), cost=0.5),
        KernelCall(f"{mod}:actuator_dynamics", (M, z(sm.nx), lin, ang, act, flex), cost=0.5),
        KernelCall(f"{mod}:reduced_bias", (sol, z(sm.nx), lin, ang, act, flex), cost=0.3),
        KernelCall(f"{mod}:ndi_command", (M, np.eye(n_q), z(n_q), sol.copy(order="F"), ang, act, n_r, kp, kv,
                                          k_att, ff, wl, np.array([0.0, 0, 0, 1]), z(3), z(sm.nv), z(law.n_m),
                                          np.array([0.0, 0, 0, 1]), z(3), z(law.n_m), z(law.n_m), z(law.n_m), flags.copy(),
                                          pinv.copy(), wrr.copy(), z(n_q)), cost=1.5),
        KernelCall(f"{mod}:ndi_observe", (M, z(law.n_m), z(3), z(n_q), lin, ang, act, flex, K_f, C_f, L, T, refresh, flags.copy(),
                                          dq.copy(), Phi.copy(), Gam.copy(), Bt.copy(), xh.copy()), cost=2.0),
        KernelCall(f"{mod}:rigid_velocity", (M, lin, ang, act, flex, z(sm.nv), z(sm.nx)), cost=0.5),
        KernelCall(f"{mod}:torque_split", (z(n_q), z(n_q), th.copy(), law.ndo, z(n_q), np.zeros((3, n_q))), cost=0.3),
    ] + ([
        KernelCall(f"{mod}:ndo_estimate", (z(n_q), flags.copy(), nPhi.copy(), ng.copy(), nH.copy(), th.copy()), cost=0.2),
        KernelCall(f"{mod}:ndo_refresh", (np.eye(n_q), z(n_q), z(n_q), z(n_q), Q_d, T, flags.copy(), nPhi.copy(), ng.copy(),
                                          nH.copy()), cost=1.0),
    ] if law.ndo else [])


def build_ndi(spec, sm: SystemModel, period: float, results_dir=None, mission_dir=None,
              any_gains: bool = False) -> NdiObserver:
    """NdiObserver from a mission's ``simulation.ndi`` (and ``gains.yaml`` when gains are not inline).
    ``any_gains``: without gains.yaml, unit gains and a zero observer gain of the right shapes (a law to
    list the kernel calls of, ``sms warmup``; never to run)."""
    from pathlib import Path

    from sms_cli.errors import InputError, Problem

    kp, kv, L = spec.kp, spec.kv, spec.L
    Q_d = spec.Q_d if spec.disturbance_observer else None
    if spec.Q_d is not None and spec.ndo_bandwidth is not None:
        raise InputError(problems=[Problem("simulation.ndi gives both Q_d and ndo_bandwidth", field="simulation.ndi.Q_d",
                                           hint="keep one: Q_d = ndo_bandwidth · M◇ is what ndo_bandwidth designs")])
    plant = None
    if spec.model_errors is not None:  # the law inverts and observes its own, erroneous copy of the model
        from sms_cli.model.model_errors import law_model

        e = spec.model_errors
        plant, sm = sm, law_model(sm, e.inertia, e.com, e.modal_frequency, e.seed)
    if L == "kalman" or (spec.disturbance_observer and spec.ndo_bandwidth is not None):  # designs on the law's model
        from sms_cli.sim.laws.ndi_gains import kalman_gain, ndo_gain

        if L == "kalman":
            L = kalman_gain(sm, spec.kalman.process, spec.kalman.measurement)
        if spec.disturbance_observer and spec.ndo_bandwidth is not None:
            Q_d = ndo_gain(sm, spec.ndo_bandwidth)
    for given in ("Q_d", "ndo_bandwidth"):
        if getattr(spec, given) is not None and not spec.disturbance_observer:
            raise InputError(problems=[Problem(f"simulation.ndi gives {given} but the disturbance observer is off",
                                               field=f"simulation.ndi.{given}", hint="add disturbance_observer: true")])
    if kp is None or kv is None or L is None or (spec.disturbance_observer and Q_d is None):
        from sms_cli.synthesis.gains_io import read_gains

        candidates = [Path(mission_dir) / spec.gains] if spec.gains and mission_dir else []
        candidates += [Path(results_dir) / (spec.gains or "gains.yaml")] if results_dir else []
        path = next((c for c in candidates if c.exists()), None)
        if path is None and any_gains:
            n_q = len(sm.wheels) + len(sm.arm)
            return NdiObserver(sm, 1.0, 1.0, np.zeros((2 * sm.reduced.K_f.shape[0] + 3, 3)), spec.attitude_gain, period,
                               spec.wheel_feedforward, np.eye(n_q) if spec.disturbance_observer else None)
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
        if spec.disturbance_observer and Q_d is None:
            if g.observer.Q_d is None:
                raise InputError(problems=[Problem(
                    f"{path}: the disturbance observer needs Q_d, which these gains do not have", field="simulation.ndi",
                    hint="synthesize with synthesis.lmi.variant: ndi_observer_ndo, or give simulation.ndi.Q_d")])
            Q_d = g.observer.Q_d
    try:
        law = NdiObserver(sm, np.asarray(kp, float), np.asarray(kv, float), np.asarray(L, float),
                          spec.attitude_gain, period, spec.wheel_feedforward,
                          None if Q_d is None else np.asarray(Q_d, float))
        law.plant = plant
        return law
    except ValueError as exc:
        raise InputError(problems=[Problem(str(exc), field="simulation.ndi")]) from None
