"""The compiled loop of the missions controlled by Kraiem 2022's NDI + observer (``ndi_law``), with the
base-mounted flexible modes of the plant: sense → NDI of the wheels and the arm at the control rate (ZOH),
wheel and joint torque limits → RKMK4 plant sub-steps of the rigid tree with the modal appendages
(``dynamics.rkmk4_step``, the ``CompiledPlant`` step; ``stops.stop_step`` with the joint stops) → the
per-tick trace and the per-step states the recorder samples from.

It is the sequence of ``sms_cli.sim.engine.Simulation.run_python`` for those missions (the compiled
engine's ``runner.unsupported_reason`` says which): one phase (or a slice of one) per call; the runner
changes the tree's body inertias between phases when a payload is attached or released.
tests/test_compiled_ndi.py checks the two loops against each other.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from sms_cli.sim.compiled import JIT
from sms_cli.sim.compiled.arm_laws import joint_reference
from sms_cli.sim.compiled.control import error_angle, limited_torque, may_reach_limit
from sms_cli.sim.compiled.dynamics import joint_transforms, momenta_energy, quat_to_matrix, rkmk4_step, workspace
from sms_cli.sim.compiled.loop import (ARM_BLOCKS, ARM_ERR, ARM_RATE, ARM_RATE_REF, ARM_REF, ARM_STOP_PEN, ARM_STOP_TIME,
                                       ARM_TORQUE, MODAL_LIMIT, NON_FINITE, RATE_LIMIT, RUNNING, SETTLED, STOP_FAILED,
                                       effective_wheel_inertia)
from sms_cli.sim.compiled.modal import modal_momentum_energy, modal_sample_momenta  # noqa: F401  (re-exported)
from sms_cli.sim.compiled.ndi_law import (SATURATED, actuator_dynamics, augmented_bias, augmented_mass, ndi_command,
                                          ndi_observe, ndi_velocity, ndo_estimate, ndo_refresh, reduced_bias, rigid_velocity,
                                          torque_split)
from sms_cli.sim.compiled.sensors import measure_state
from sms_cli.sim.compiled.stops import stop_step

@njit(**JIT)
def run_ticks_ndi(
    # tree
    parent, kind, axis, place_R, place_p, inertia, leaf_IA, mass, com, armature, idx_q, idx_v,
    # base-mounted modes: B (n_η×6), Bᵀ, BᵀB, −Ω², −2ζΩ (CompiledPlant)
    modal_B, modal_Bt, modal_BtB, neg_omega2, neg_2zo,
    # the law's model (NdiObserver.model_arrays; the plant's own arrays without model errors): the tree's body
    # inertias, B, −Ω², −2ζΩ
    law_inertia, law_B, law_neg_omega2, law_neg_2zo,
    # wheels
    wheel_v, max_torque, max_speed, coulomb, viscous,
    # NDI law (ndi_law; NdiObserver.kernel_args) on this phase or not, and its state (in/out)
    ndi_on, lin, ang, act, flex, n_r, kp, kv, k_att, wheel_ff, wheel_limit, K_f, C_f, L, period, refresh, flags,
    wheel_pinv, wheel_rate_ref, disc_q, Phi, Gamma, B_tau, x_hat,
    # its disturbance observer (ndo_estimate, ndo_refresh): on, Q_d, state in/out
    ndo_on, Q_d, ndo_Phi, ndo_g, ndo_H, tau_hat,
    # the phase's attitude reference (step: ω_r = 0) and settling
    q_ref, settle_tol, settle_time,
    # arm: coordinates, effort limits, the phase's joint reference (arm_laws.joint_reference) and its start
    arm_q, arm_v, effort, ref_times, ref_points, ref_step, t_phase0,
    # joint stops (stops.stop_step): on, table, restitution; state in/out
    stop_on, sj_arm, sj_v, sj_q, sj_lower, sj_upper, restitution, sj_side, sj_rebound, sj_since,
    # sensors (sensors.measure_state): noisy or biased, parameters, the normals of each tick (n_ticks × K)
    sensed, sens_par, sens_noise,
    # timing and limits
    t0, dt, n_sub, tick0, n_ticks, max_rate, max_modal,
    # state, in/out
    q, v, eta, etadot, eff_inertia, settled_since,
    # outputs per control tick
    tr_t, tr_err, tr_ws, tr_tw, tr_sat, tr_mom, tr_energy, tr_arm, tr_wrr, tr_modal, tr_split,
    # outputs per plant step (state after the step and the wheel torque applied during it)
    st_t, st_q, st_v, st_eta, st_etadot, st_tw,
    # joint-stop events (stops.py rows) and their count
    ev, ev_n,
):
    """Advance up to ``n_ticks`` control periods from time t0; returns (ticks, steps, status) as
    ``loop.run_ticks`` (status also MODAL_LIMIT). Per tick: the NDI torques (wheels then arm, when
    ``ndi_on``) from the law's M and r (``law_*``: its model, with errors or the plant's) at the estimated state (``augmented_mass``, ``ndi_velocity``,
    ``augmented_bias``, ``ndi_command``; with ``ndo_on`` the disturbance estimate ``ndo_estimate`` subtracted),
    clipped to the wheel and joint limits, the observer propagated with them (``ndi_observe``, ``ndo_refresh``); the trace (``tr_arm`` blocks as ``run_ticks``, ``tr_wrr`` the law's desired
    wheel rates, ``tr_modal`` max |η|, momenta and energy with the modal terms, ``tr_split`` the command's feedback,
    linearising and disturbance parts, ``ndi_law.torque_split``, flattened; zero where the law is off); then the plant
    sub-steps.
    Sensors (``sensed``): the law sees the measured state of each tick (``sensors.measure_state`` with the tick's
    row of ``sens_noise``: ω, the attitude, the arm's angles and rates), the trace and the plant the true one."""
    nv = v.shape[0]
    nq = q.shape[0]
    nx = nv + eta.shape[0]
    ne = eta.shape[0]
    nw = wheel_v.shape[0]
    n = parent.shape[0]
    n_arm = arm_q.shape[0]
    na = act.shape[0]
    ns = sj_v.shape[0]
    omega = np.empty(3)
    ws = np.empty(nw)
    tau_w = np.zeros(nw)
    tau_applied = np.zeros(nw)
    tau = np.zeros(nv)
    tau_a = np.zeros(na)
    q_new, v_new = np.empty(nq), np.empty(nv)
    eta_new, etadot_new = np.empty(ne), np.empty(ne)
    work = workspace(n, nq, nv, ne)
    no_i, no_f = np.zeros(0, dtype=np.int64), np.zeros(0)
    modal = (modal_Bt, modal_BtB, neg_omega2, neg_2zo)
    R_rel = np.empty((n, 3, 3))
    p_rel = np.empty((n, 3))
    me = np.empty(10)
    M = np.empty((nx, nx))
    r = np.empty(nx)
    n_cmd = np.empty(na)
    r_lin = np.empty(nx)
    x_lin = np.empty(nx)
    zero_e = np.zeros(ne)
    split = np.zeros((3, na))
    qdot_a = np.empty(na)
    x = np.empty(nx)
    zero3 = np.zeros(3)
    ref_q, ref_qd, ref_qdd = np.empty(n_arm), np.empty(n_arm), np.empty(n_arm)
    q_arm, tau_m = np.empty(n_arm), np.zeros(n_arm)
    on_time, pen_max = np.zeros(ns), np.zeros(ns)
    Rb = np.empty((3, 3))
    tree_a = (parent, kind, axis, place_R, place_p, inertia, leaf_IA, armature, idx_q, idx_v)
    n_f = flex.shape[0]
    q_m, v_m = np.empty(nq), np.empty(nv)  # the measured state (noisy sensors)
    t = t0
    steps = 0
    for k in range(n_ticks):
        tick = tick0 + k
        if sensed:
            measure_state(sens_par, sens_noise[k], arm_q, arm_v, q, v, q_m, v_m)
            qs, vs = q_m, v_m
        else:
            qs, vs = q, v
        for a in range(3):
            omega[a] = vs[3 + a]
        for i in range(nw):
            ws[i] = v[wheel_v[i]]
            tau_w[i] = 0.0
        sat = False
        joint_transforms(kind, axis, place_R, place_p, idx_q, q, R_rel, p_rel)  # the trace's momenta: the true state
        momenta_energy(parent, kind, axis, inertia, mass, com, armature, idx_v, R_rel, p_rel, v, me, work)
        modal_momentum_energy(q, v, eta, etadot, modal_B, neg_omega2, mass, com, work[16], work[17], me)
        if sensed:  # the law's model: the measured state
            joint_transforms(kind, axis, place_R, place_p, idx_q, qs, R_rel, p_rel)
        if n_arm:
            joint_reference(ref_times, ref_points, ref_step, t - t_phase0, ref_q, ref_qd, ref_qdd)
        for i in range(n_arm):
            q_arm[i] = qs[arm_q[i]]
            tau_m[i] = 0.0
        if ndi_on:
            augmented_mass(parent, kind, axis, law_inertia, armature, idx_v, R_rel, p_rel, law_B, M)
            ndi_velocity(M, lin, ang, act, flex, omega, vs, x_hat, flags, x)
            augmented_bias(parent, kind, axis, law_inertia, idx_v, R_rel, p_rel, law_B, law_neg_omega2, law_neg_2zo, x[:nv],
                           x_hat[n_f - ne:n_f], x[nv:], r)
            M_dia, n_term, sol = actuator_dynamics(M, r, lin, ang, act, flex)
            n_cmd[:] = n_term
            if ndo_on:  # τ = M◇ v + n − τ̂_d (Kraiem 2022 (4.21))
                for i in range(na):
                    qdot_a[i] = vs[act[i]]
                ndo_estimate(qdot_a, flags, ndo_Phi, ndo_g, ndo_H, tau_hat)
                for i in range(na):
                    n_cmd[i] -= tau_hat[i]
            ndi_command(M, M_dia, n_cmd, sol, ang, act, n_r, kp, kv, k_att, wheel_ff, wheel_limit, qs[3:7], omega, vs, q_arm,
                        q_ref, zero3, ref_q, ref_qd, ref_qdd, flags, wheel_pinv, wheel_rate_ref, tau_a)
            rigid_velocity(M, lin, ang, act, flex, vs, x_lin)
            augmented_bias(parent, kind, axis, law_inertia, idx_v, R_rel, p_rel, law_B, law_neg_omega2, law_neg_2zo,
                           x_lin[:nv], zero_e, zero_e, r_lin)
            torque_split(n_term, reduced_bias(sol, r_lin, lin, ang, act, flex), tau_hat, ndo_on, tau_a, split)
            sat = flags[SATURATED] != 0
            for i in range(nw):  # actuators.WheelArray.clip_torque
                lim = max_torque[i]
                if abs(tau_a[i]) > lim * (1 + 1e-12):
                    sat = True
                tau_w[i] = min(max(tau_a[i], -lim), lim)
                tau_a[i] = tau_w[i]
            for i in range(n_arm):  # actuators.clip_joint_torque
                lim = effort[i]
                if abs(tau_a[nw + i]) > lim * (1 + 1e-12):
                    sat = True
                tau_m[i] = min(max(tau_a[nw + i], -lim), lim)
                tau_a[nw + i] = tau_m[i]
            ndi_observe(M, q_arm, omega, tau_a, lin, ang, act, flex, K_f, C_f, L, period, refresh, flags, disc_q, Phi, Gamma,
                        B_tau, x_hat)
            if ndo_on:
                ndo_refresh(M_dia, n_term, qdot_a, tau_a, Q_d, period, flags, ndo_Phi, ndo_g, ndo_H)
        # trace (state at the tick)
        if n_arm:
            for i in range(n_arm):
                tr_arm[k, ARM_ERR * n_arm + i] = ref_q[i] - q[arm_q[i]]
                tr_arm[k, ARM_REF * n_arm + i] = ref_q[i]
                tr_arm[k, ARM_RATE_REF * n_arm + i] = ref_qd[i]
                tr_arm[k, ARM_RATE * n_arm + i] = v[arm_v[i]]
                tr_arm[k, ARM_TORQUE * n_arm + i] = tau_m[i]
                tr_arm[k, ARM_STOP_TIME * n_arm + i] = 0.0
            for j in range(ns):
                xj = q[sj_q[j]]
                tr_arm[k, ARM_STOP_PEN * n_arm + sj_arm[j]] = max(0.0, max(xj - sj_upper[j], sj_lower[j] - xj))
            quat_to_matrix(q[3], q[4], q[5], q[6], Rb)
            vc0 = v[0] + v[4] * com[0, 2] - v[5] * com[0, 1]
            vc1 = v[1] + v[5] * com[0, 0] - v[3] * com[0, 2]
            vc2 = v[2] + v[3] * com[0, 1] - v[4] * com[0, 0]
            o = ARM_BLOCKS * n_arm
            for a in range(3):
                tr_arm[k, o + a] = q[a]
                tr_arm[k, o + 3 + a] = mass[0] * (Rb[a, 0] * vc0 + Rb[a, 1] * vc1 + Rb[a, 2] * vc2)
        tr_t[k] = t
        tr_err[k] = error_angle(q[3:7], q_ref)
        for i in range(nw):
            tr_ws[k, i] = ws[i]
            tr_tw[k, i] = tau_w[i]
            tr_wrr[k, i] = wheel_rate_ref[i]
        tr_sat[k] = sat
        for a in range(3):
            tr_mom[k, a] = me[a]
            tr_mom[k, 3 + a] = me[6 + a]
        tr_energy[k] = me[9]
        peak = 0.0
        for i in range(ne):
            peak = max(peak, abs(eta[i]))
        tr_modal[k] = peak
        for c in range(3):  # zero where the law is off: ndi_on is the same for every tick of a call
            for i in range(na):
                tr_split[k, c * na + i] = split[c, i]
        if nw and tick % 10 == 0:
            effective_wheel_inertia(parent, kind, axis, place_R, place_p, inertia, leaf_IA, armature, idx_q, idx_v, q, wheel_v,
                                    eff_inertia, work)
        tau[:] = 0.0
        live = nw > 0 and (may_reach_limit(ws, tau_w, eff_inertia, max_speed, n_sub * dt)
                           or coulomb != 0.0 or viscous != 0.0)
        for i in range(nw):
            tau[wheel_v[i]] = tau_w[i]
            tau_applied[i] = tau_w[i]
        for i in range(n_arm):
            tau[arm_v[i]] = tau_m[i]
        for j in range(ns):
            on_time[j] = 0.0
            pen_max[j] = 0.0
        for _ in range(n_sub):
            if live:
                for i in range(nw):
                    ws[i] = v[wheel_v[i]]
                limited_torque(tau_w, ws, eff_inertia, max_speed, dt, coulomb, viscous, tau_applied)
                for i in range(nw):
                    tau[wheel_v[i]] = tau_applied[i]
            if stop_on:
                if not stop_step(tree_a, sj_v, sj_q, sj_lower, sj_upper, restitution, sj_side, sj_rebound, sj_since, q, v,
                                 tau, dt, t, q_new, v_new, on_time, pen_max, ev, ev_n, work, modal, eta, etadot, eta_new,
                                 etadot_new, False):
                    return k + 1, steps, STOP_FAILED
            else:
                rkmk4_step(parent, kind, axis, place_R, place_p, inertia, leaf_IA, armature, idx_q, idx_v, modal_Bt, modal_BtB,
                           neg_omega2, neg_2zo, no_i, no_i, no_f, no_f, no_f, q, v, eta, etadot, tau, dt, q_new, v_new, eta_new,
                           etadot_new, work, no_i)  # no joint locked: stop_step's signature, one compilation
            t += dt
            st_t[steps] = t
            for a in range(nq):
                q[a] = q_new[a]
                st_q[steps, a] = q_new[a]
            for a in range(nv):
                v[a] = v_new[a]
                st_v[steps, a] = v_new[a]
            for a in range(ne):
                eta[a] = eta_new[a]
                etadot[a] = etadot_new[a]
                st_eta[steps, a] = eta_new[a]
                st_etadot[steps, a] = etadot_new[a]
            for i in range(nw):
                st_tw[steps, i] = tau_applied[i]
            steps += 1
        if stop_on:
            for j in range(ns):
                tr_arm[k, ARM_STOP_TIME * n_arm + sj_arm[j]] = on_time[j]
                tr_arm[k, ARM_STOP_PEN * n_arm + sj_arm[j]] = pen_max[j]
        vmax = 0.0
        finite = True
        for a in range(nv):
            if not math.isfinite(v[a]):
                finite = False
            vmax = max(vmax, abs(v[a]))
        for a in range(nq):
            if not math.isfinite(q[a]):
                finite = False
        emax = 0.0
        for a in range(ne):
            if not math.isfinite(eta[a]):
                finite = False
            emax = max(emax, abs(eta[a]))
        if not finite:
            return k + 1, steps, NON_FINITE
        if vmax > max_rate:
            return k + 1, steps, RATE_LIMIT
        if ne and emax > max_modal:
            return k + 1, steps, MODAL_LIMIT
        if settle_tol > 0:
            if error_angle(q[3:7], q_ref) < settle_tol:
                if math.isnan(settled_since[0]):
                    settled_since[0] = t
                if t - settled_since[0] >= settle_time:
                    return k + 1, steps, SETTLED
            else:
                settled_since[0] = math.nan
    return n_ticks, steps, RUNNING
