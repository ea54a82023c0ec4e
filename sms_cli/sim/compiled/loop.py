"""The compiled simulation loop for one phase (or a slice of one): sense → attitude law
(``attitude_laws.attitude_law``: mrp_feedback, quaternion_pd, smc, twisting_smc, backstepping) → wheel
allocation and limits (ZOH at the control rate) → RKMK4 plant sub-steps, with the per-tick trace
and the per-step states the recorder samples from.

It is the same sequence as ``sms_cli.sim.engine.Simulation.run`` for the missions the compiled
engine accepts (``runner.unsupported_reason``): rigid free-flying base, reaction wheels, an arm with
its law (``arm_laws.arm_torque``) following joint waypoints (``arm_laws.joint_reference``) and its
joint stops (``stops.stop_step``), or a momentum law of Vicariotto 2023 (``momentum_control``), real thrusters
(``thrusters.thruster_step``, the allocation by the caller), sensor noise and bias (``sensors.measure_state``),
disturbance wrenches
(``disturbances``); step or smooth attitude references (``profiles``), held-base phases (``held_base``) and
end-effector tracking (``resolved_rate``).
tests/test_compiled_engine.py and tests/test_compiled_arm.py check the two engines against each other.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from sms_cli.sim.compiled import JIT
from sms_cli.sim.compiled.arm_laws import arm_model_terms, arm_torque, joint_reference
from sms_cli.sim.compiled.attitude_laws import attitude_law, system_momentum, wheel_momentum
from sms_cli.sim.compiled.control import (allocate_and_clip, clip_attitude_torque, error_angle, error_quaternion,
                                          limited_torque, may_reach_limit)
from sms_cli.sim.compiled.dynamics import (aba_call, bias_forces, frame_poses, integrate, joint_transforms, mass_matrix,
                                           momenta_energy, quat_to_matrix, relative_poses, rkmk4_step, workspace,
                                           world_placements)
from sms_cli.sim.compiled.disturbances import disturbance_wrench
from sms_cli.sim.compiled.held_base import held_base_reaction
from sms_cli.sim.compiled.modal import modal_momentum_energy
from sms_cli.sim.compiled.momentum_control import locked_model, locked_velocity, lyapunov_terms, momentum_control
from sms_cli.sim.compiled.ndi_law import augmented_bias, augmented_mass
from sms_cli.sim.compiled.profiles import attitude_reference, reference_rates
from sms_cli.sim.compiled.resolved_rate import frame_origin, track_end_effector
from sms_cli.sim.compiled.sensors import measure_state
from sms_cli.sim.compiled.stops import stop_step
from sms_cli.sim.compiled.thrusters import USED, thruster_step

RUNNING, SETTLED, NON_FINITE, RATE_LIMIT, STOP_FAILED, ALLOCATE = 0, 1, 2, 3, 4, 5
MODAL_LIMIT = 6  # a modal amplitude exceeded the divergence limit (both loops)
# column blocks of the per-tick arm trace ``tr_arm`` (each n_arm wide, then the base motion's 6)
ARM_ERR, ARM_REF, ARM_RATE_REF, ARM_RATE, ARM_TORQUE, ARM_STOP_TIME, ARM_STOP_PEN, ARM_BLOCKS = 0, 1, 2, 3, 4, 5, 6, 7
# columns of the per-tick ``tr_x``: the attitude reference (xyzw), the end-effector error (m; NaN: not tracking),
# the held base's reaction [f; n] (base frame; NaN: base not held)
X_REF, X_EE_ERR, X_REACTION, X_N = 0, 4, 5, 11
# ``rr_par``: gain K (3, 1/s), damping, threshold, control rate (Hz), generalized (1) or fixed-base (0) Jacobian,
# target at the phase start (3, m, world), target velocity (3, m/s)
RR_GAIN, RR_DAMPING, RR_THRESHOLD, RR_RATE, RR_GENERALIZED, RR_TARGET, RR_VEL, RR_N = 0, 3, 4, 5, 6, 7, 10, 13


@njit(**JIT)
def effective_wheel_inertia(parent, kind, axis, place_R, place_p, inertia, leaf_IA, armature, idx_q, idx_v, q, wheel_v, out,
                            ws):
    """1 / (M⁻¹)_ii for each wheel velocity index: the inertia its relative speed sees at q
    (``WheelArray.update_effective_inertia``); columns of M⁻¹ by ABA at zero velocity."""
    nv = armature.shape[0]
    R_rel, p_rel = ws[8], ws[9]
    joint_transforms(kind, axis, place_R, place_p, idx_q, q, R_rel, p_rel)
    zero = np.zeros(nv)
    tau = np.zeros(nv)
    col = np.empty(nv)
    for k in range(wheel_v.shape[0]):
        tau[:] = 0.0
        tau[wheel_v[k]] = 1.0
        aba_call(parent, kind, axis, inertia, leaf_IA, armature, idx_v, R_rel, p_rel, zero, tau, np.zeros((6, 6)), np.zeros(6),
                 col, ws)
        out[k] = 1.0 / col[wheel_v[k]]


_BASE_ANGULAR = np.array([3, 4, 5], dtype=np.int64)


@njit(**JIT)
def system_inertia(parent, kind, axis, inertia, armature, idx_v, R_rel, p_rel, elim, M, out):
    """The locked attitude inertia (3×3, base frame, about the system CoM; ``plant_models.effective_inertia``)
    at the joint transforms (R_rel, p_rel): the Schur complement of H on the base angular block after
    eliminating the coordinates ``elim`` (base linear, wheels), symmetrised (M: nv×nv scratch)."""
    mass_matrix(parent, kind, axis, inertia, armature, idx_v, R_rel, p_rel, M)
    arm_model_terms(M, np.zeros(M.shape[0]), _BASE_ANGULAR, elim, out, np.empty(3))


@njit(**JIT)
def run_ticks(
    # tree
    parent, kind, axis, place_R, place_p, inertia, leaf_IA, mass, com, armature, idx_q, idx_v,
    # base-mounted modes (none: n_η = 0): B (n_η×6), Bᵀ, BᵀB, −Ω², −2ζΩ (CompiledPlant, ndi_loop.run_ticks_ndi)
    modal_B, modal_Bt, modal_BtB, neg_omega2, neg_2zo,
    # wheels
    wheel_v, A_pinv, null, spin, null_gain, target_speed, max_torque, max_speed, coulomb, viscous,
    # attitude law (attitude_laws.attitude_law: code, parameters, body) and phase
    law_on, thrusters, torque_limit, law_code, law_par, J_law, G_law, Js_law, body_code, fd_step, att_prof,
    settle_tol, settle_time,
    # momentum law instead (momentum_control; code 0: none): code, model tuple, gains, state and the last W, in/out
    mom_code, mom_model, mom_par, mom_mem, mom_W,
    # arm: coordinates, law (arm_laws.arm_torque; code −1: none) with its model's indices (arm_model_terms),
    # effort limits, the phase's joint reference (arm_laws.joint_reference) and its start time
    arm_q, arm_v, arm_code, arm_par, arm_wrap, arm_a, arm_p, effort, ref_times, ref_points, ref_step, t_phase0,
    # joint stops (stops.stop_step): on, table (arm index, v and q indices, limits), restitution; state in/out
    stop_on, sj_arm, sj_v, sj_q, sj_lower, sj_upper, restitution, sj_side, sj_rebound, sj_since,
    # held base (held_base.py) and end-effector tracking (resolved_rate.track_end_effector: on, parameters RR_*,
    # rate limits, the end-effector frame; the tracked joint reference, in/out); the disturbances' table
    # (disturbances.py: rows DIST_*, none: no rows)
    held, rr_on, rr_par, rr_rate, ee_joint, ee_R, ee_p, q_track, dist,
    # real thrusters (thrusters.thruster_step): on, probe (stop before the plant steps with the commanded wrench in
    # thr_cmd), the set's tuple, the firing pattern (start, on-times), state in/out, commanded wrench out
    thr_on, thr_probe, thr, thr_t0, thr_on_times, thr_state, thr_cmd,
    # sensors (sensors.measure_state): noisy or biased, parameters, the normals of each tick (n_ticks × K)
    sensed, sens_par, sens_noise,
    # timing and limits
    t0, dt, n_sub, tick0, n_ticks, max_rate, max_modal,
    # state, in/out
    q, v, eta, etadot, law_mem, eff_inertia, settled_since,
    # outputs per control tick (tr_modal: max |η|)
    tr_t, tr_err, tr_ws, tr_tw, tr_sat, tr_bt, tr_mom, tr_energy, tr_arm, tr_x, tr_locked, tr_lyap, tr_wrench, tr_modal,
    # outputs per plant step (state after the step and the wheel torque applied during it; the momentum law's W terms)
    st_t, st_q, st_v, st_eta, st_etadot, st_tw, st_lyap,
    # per plant step with real thrusters: [thrust averaged over the step (n), propellant used] and [p, k, μ] at the mass
    st_thr, st_mom,
    # joint-stop events (stops.py rows) and their count
    ev, ev_n,
):
    """Advance up to ``n_ticks`` control periods from time t0; returns (ticks, steps, status).

    status: RUNNING (all ticks done), SETTLED (the phase's until_settled condition ended it),
    NON_FINITE, RATE_LIMIT or MODAL_LIMIT (divergence: the state at the last completed tick is in q, v),
    STOP_FAILED (a joint-stop complementarity problem did not terminate).

    Flexible modes (n_η > 0, appendages on the base): the plant steps (η, η̇) with the rigid tree (the
    ``CompiledPlant`` step, ``stop_step`` with the joint stops); the laws see the rigid measured state, the arm
    law's model (M*, h*) is reduced from the augmented mass matrix and bias at the measured (q, v) and the true
    (η, η̇) (``augmented_mass``, ``augmented_bias``; ``plant_models.ArmDynamics``: free modes are sensed as they
    are); the trace's momenta and energy have the modal terms (``modal.modal_momentum_energy``), ``tr_modal``
    max |η| at the tick.

    The arm (n_arm joints): the law's torque on the tick's joint reference, clipped to the effort
    limits (a clipped joint counts as saturated), with M* and h* from ``mass_matrix`` and
    ``bias_forces`` for the laws that use the model; ``tr_arm`` gets per tick the blocks ARM_* (the
    joint error q_d − q, q_d, q̇_d, q̇, the joint torque, the time on stop and the largest penetration
    over the tick's steps) and the base motion ([base origin; base-body momentum], world;
    ``base_motion.base_kinematics``).

    The attitude reference of each tick is the phase's profile ``att_prof`` at t − t_phase0
    (``profiles.attitude_reference``: step, or the smooth slew with its ω_ref, ω̇_ref, which the law sees in
    the base frame, ``profiles.reference_rates``). ``held``: the base is held (its coordinates locked in the
    plant step, the support's wrench in ``tr_x``). ``rr_on``: the arm's reference comes from the resolved rate
    (``resolved_rate.track_end_effector`` on the target rr_par[RR_TARGET] + rr_par[RR_VEL] (t − t_phase0)),
    integrated in q_track; ``tr_x`` gets per tick the columns X_* (reference, end-effector error, reaction).

    The law sees the constant inertia J_law with J̇ = 0 and the
    internal momentum h from the wheels (body_code 0: G_law, Js_law, ``RigidBody``) or from the
    system's momentum about its CoM (body_code 1: h = Rᵀk_G − J ω, ``SystemBody``), or the online
    inertia (body_code 2: ``SystemBody(online=True)``): J(q) the locked inertia (``system_inertia``) and
    J̇ its central difference along v with the step fd_step, h as for body_code 1.

    A momentum law (mom_code > 0, ``momentum_control``) replaces the attitude law: its wheel torques (clipped)
    and its base wrench (applied as an ideal source); ``tr_locked``/``tr_lyap``/``tr_wrench`` get per tick μ, the last W and the wrench
    (``mom_W``, the phase start's or the last step's), ``st_lyap`` W and its terms after every step.

    Real thrusters (thr_on; ``thrusters.thruster_step``): the wrench the law would apply is the thrusters' command,
    allocated by the caller (``ThrusterDrive.command``, an LP): a probe call (thr_probe) returns ALLOCATE at the
    first tick's control with that wrench in thr_cmd (the caller restores the laws' state it changed), then the
    call with the pattern (thr_t0, thr_on_times) steps the plant through the firings, the base body losing the
    propellant spent (the tree's inertia, mass and com arrays change in place); the momentum law then takes its
    locked/shape quantities from the mass matrix at the current mass (``locked_model``).

    Sensors (``sensed``): the laws (attitude, momentum, arm, resolved rate) see the measured state of each tick
    (``sensors.measure_state`` with the tick's row of ``sens_noise``), the trace, the held base's reaction, the wheel
    model and the plant the true one."""
    nv = v.shape[0]
    nq = q.shape[0]
    nw = wheel_v.shape[0]
    n = parent.shape[0]
    zero33 = np.zeros((3, 3))
    h = np.zeros(3)
    T = np.zeros(3)
    qe = np.empty(4)
    omega = np.empty(3)
    ws = np.empty(nw)
    tau_w = np.zeros(nw)
    tau_applied = np.zeros(nw)
    tau = np.zeros(nv)
    q_new = np.empty(nq)
    v_new = np.empty(nv)
    ne = eta.shape[0]
    nx = nv + ne
    work = workspace(n, nq, nv, ne)
    # the base-mounted modes as the plant step takes them; no springs (the general step takes them)
    modal = (modal_Bt, modal_BtB, neg_omega2, neg_2zo)
    no_e = np.zeros(0)
    no_i = np.zeros(0, dtype=np.int64)
    eta_new, etadot_new = np.empty(ne), np.empty(ne)
    R_rel = np.empty((n, 3, 3))
    p_rel = np.empty((n, 3))
    me = np.empty(10)
    n_arm = arm_q.shape[0]
    ns = sj_v.shape[0]
    ref_q, ref_qd, ref_qdd = np.empty(n_arm), np.empty(n_arm), np.empty(n_arm)
    q_arm, qd_arm, tau_m = np.empty(n_arm), np.empty(n_arm), np.zeros(n_arm)
    na_model = arm_a.shape[0]
    M_full, n_full = np.empty((nv, nv)), np.empty(nv)
    M_aug, n_aug = np.empty((nx, nx)), np.empty(nx)  # the arm model's (augmented: modes included)
    Mstar, hstar = np.empty((na_model, na_model)), np.empty(na_model)
    model_law = arm_code == 2 or arm_code == 3  # arm_laws.MODEL_LAWS
    on_time, pen_max = np.zeros(ns), np.zeros(ns)
    Rb = np.empty((3, 3))
    # online inertia (body_code 2): the coordinates eliminated from the locked inertia (base linear, wheels)
    elim = np.empty(3 + nw, dtype=np.int64)
    for a in range(3):
        elim[a] = a
    for i in range(nw):
        elim[3 + i] = wheel_v[i]
    J_on, Jd_on, J_pm = np.empty((3, 3)), np.empty((3, 3)), np.empty((2, 3, 3))
    dq, q_fd = np.empty(nv), np.empty(nq)
    R_fd, p_fd = np.empty((n, 3, 3)), np.empty((n, 3))
    # the attitude reference of the tick (profiles.attitude_reference) and its rates in the base frame
    q_ref, w_ref, wd_ref, om_r, dom_r = np.empty(4), np.empty(3), np.empty(3), np.empty(3), np.empty(3)
    # a held base: its coordinates locked in the plant step, the support's wrench in the trace
    base_lock = np.empty(6 if held else 0, dtype=np.int64)
    for a in range(base_lock.shape[0]):
        base_lock[a] = a
    tau_h, react = np.zeros(nv), np.empty(6)
    dw = np.empty(6)  # the disturbances' wrench at a plant step
    # end-effector tracking: world placements, Jacobians, the target
    oR_w, op_w = np.empty((n, 3, 3)), np.empty((n, 3))
    J_ee, Jm_rr, Jr_rr, ee_pos, target = np.empty((6, nv)), np.empty((6, n_arm)), np.empty((6, nw)), np.empty(3), np.empty(3)
    tree_a = (parent, kind, axis, place_R, place_p, inertia, leaf_IA, armature, idx_q, idx_v)
    tree_t = (parent, kind, axis, place_R, place_p, inertia, leaf_IA, mass, com, armature, idx_q, idx_v)
    wrench = np.zeros(6)
    impulse = np.zeros(thr_on_times.shape[0])
    mom_vary = thr_on and mom_code > 0  # the law's quantities follow the propellant spent
    # without a momentum law (mom_model None) or real thrusters (thr None) numba prunes their blocks below (``is not
    # None`` on an argument): the other missions do not compile the momentum laws and the thrusters' step
    law_model = mom_model
    M_mom = np.empty((nv, nv))
    # the measured state the laws see (qs, vs) and, with noisy sensors, the true state's transforms and momenta
    # for the trace (R_t, p_t, me_t; without: the laws' own)
    q_m, v_m = np.empty(nq), np.empty(nv)
    R_t = np.empty((n, 3, 3)) if sensed else R_rel
    p_t = np.empty((n, 3)) if sensed else p_rel
    me_t = np.empty(10) if (sensed or ne > 0) else me  # with modes: the rigid me for the laws, me_t with the modal terms
    oR_t, op_t = np.empty((n, 3, 3)), np.empty((n, 3))
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
        attitude_reference(att_prof, t - t_phase0, q_ref, w_ref, wd_ref)
        ee_err = math.nan
        # control (held over the period)
        T[:] = 0.0
        tau_w[:] = 0.0
        sat = False
        joint_transforms(kind, axis, place_R, place_p, idx_q, qs, R_rel, p_rel)
        momenta_energy(parent, kind, axis, inertia, mass, com, armature, idx_v, R_rel, p_rel, vs, me, work)
        if sensed:
            joint_transforms(kind, axis, place_R, place_p, idx_q, q, R_t, p_t)
            momenta_energy(parent, kind, axis, inertia, mass, com, armature, idx_v, R_t, p_t, v, me_t, work)
        elif ne > 0:
            for a in range(10):
                me_t[a] = me[a]
        if ne > 0:  # work[16], work[17]: the true state's world placements, as momenta_energy leaves them
            modal_momentum_energy(q, v, eta, etadot, modal_B, neg_omega2, mass, com, work[16], work[17], me_t)
        mom_on = False
        if mom_model is not None:
            if mom_vary:
                joint_transforms(kind, axis, place_R, place_p, idx_q, qs, R_rel, p_rel)
                mass_matrix(parent, kind, axis, inertia, armature, idx_v, R_rel, p_rel, M_mom)
                law_model = locked_model(M_mom, wheel_v)
            if mom_code > 0:
                locked_velocity(v, law_model, tr_locked[k])
                tr_lyap[k] = mom_W[0]
            if law_on and mom_code > 0:
                mom_on = True
                sat = momentum_control(mom_code, qs, vs, q_ref, law_model, mom_par, mom_mem, max_torque, tau_w, wrench)
                for a in range(3):
                    T[a] = wrench[3 + a]
                for a in range(6):
                    tr_wrench[k, a] = wrench[a]
        if law_on and not mom_on:
            error_quaternion(qs[3:7], q_ref, qe)
            reference_rates(qe, w_ref, wd_ref, om_r, dom_r)
            if body_code == 2:  # SystemBody.inertia, inertia_rate
                system_inertia(parent, kind, axis, inertia, armature, idx_v, R_rel, p_rel, elim, M_full, J_on)
                for a in range(nv):
                    dq[a] = fd_step * vs[a]
                for sgn in range(2):
                    integrate(kind, axis, idx_q, idx_v, qs, dq, q_fd)
                    joint_transforms(kind, axis, place_R, place_p, idx_q, q_fd, R_fd, p_fd)
                    system_inertia(parent, kind, axis, inertia, armature, idx_v, R_fd, p_fd, elim, M_full, J_pm[sgn])
                    for a in range(nv):
                        dq[a] = -fd_step * vs[a]
                for a in range(3):
                    for b in range(3):
                        Jd_on[a, b] = (J_pm[0, a, b] - J_pm[1, a, b]) / (2.0 * fd_step)
            if body_code >= 1:
                system_momentum(qs[3:7], me[3:6], J_on if body_code == 2 else J_law, omega, h)
            else:
                wheel_momentum(G_law, Js_law, omega, ws, h)
            if body_code == 2:
                attitude_law(law_code, qe, omega, om_r, dom_r, ws, J_on, Jd_on, h, G_law, Js_law, law_par, law_mem, t, T)
            else:
                attitude_law(law_code, qe, omega, om_r, dom_r, ws, J_law, zero33, h, G_law, Js_law, law_par, law_mem, t, T)
            if thrusters:
                sat = clip_attitude_torque(T, torque_limit)
            else:
                sat = allocate_and_clip(T, ws, A_pinv, null, spin, null_gain, target_speed, max_torque, tau_w)
        # arm: reference, law, effort limits
        if n_arm:
            if rr_on:  # the resolved rate's joint rates, integrated into the tracked reference
                world_placements(parent, R_rel, p_rel, oR_w, op_w)
                if rr_par[RR_GENERALIZED] != 0.0:
                    mass_matrix(parent, kind, axis, inertia, armature, idx_v, R_rel, p_rel, M_full)
                for a in range(3):
                    target[a] = rr_par[RR_TARGET + a] + rr_par[RR_VEL + a] * (t - t_phase0)
                ee_err = track_end_effector(parent, kind, axis, idx_v, oR_w, op_w, ee_joint, ee_R, ee_p, M_full, arm_v, wheel_v,
                                            vs, target, rr_par[RR_VEL:RR_VEL + 3], rr_par[RR_GAIN:RR_GAIN + 3],
                                            rr_par[RR_DAMPING], rr_par[RR_THRESHOLD], rr_rate,
                                            rr_par[RR_GENERALIZED] != 0.0, J_ee, Jm_rr, Jr_rr, ref_qd, ee_pos)
                if sensed:  # the trace's error: the true end effector's
                    world_placements(parent, R_t, p_t, oR_t, op_t)
                    frame_origin(oR_t, op_t, ee_joint, ee_p, ee_pos)
                    ee_err = math.sqrt((target[0] - ee_pos[0]) ** 2 + (target[1] - ee_pos[1]) ** 2 + (target[2] - ee_pos[2]) ** 2)
                for i in range(n_arm):
                    q_track[i] = q_track[i] + ref_qd[i] / rr_par[RR_RATE]
                    ref_q[i] = q_track[i]
                    ref_qdd[i] = 0.0
            else:
                joint_reference(ref_times, ref_points, ref_step, t - t_phase0, ref_q, ref_qd, ref_qdd)
            for i in range(n_arm):
                q_arm[i] = qs[arm_q[i]]
                qd_arm[i] = vs[arm_v[i]]
                tau_m[i] = 0.0
            if arm_code >= 0:
                if model_law and ne > 0:  # the augmented model, the true (η, η̇) (Sensed.eta, etadot)
                    augmented_mass(parent, kind, axis, inertia, armature, idx_v, R_rel, p_rel, modal_B, M_aug)
                    augmented_bias(parent, kind, axis, inertia, idx_v, R_rel, p_rel, modal_B, neg_omega2, neg_2zo, vs, eta,
                                   etadot, n_aug)
                    arm_model_terms(M_aug, n_aug, arm_a, arm_p, Mstar, hstar)
                elif model_law:
                    mass_matrix(parent, kind, axis, inertia, armature, idx_v, R_rel, p_rel, M_full)
                    bias_forces(parent, kind, axis, inertia, idx_v, R_rel, p_rel, vs, n_full)
                    arm_model_terms(M_full, n_full, arm_a, arm_p, Mstar, hstar)
                arm_torque(arm_code, arm_par, arm_wrap, ref_q, ref_qd, ref_qdd, q_arm, qd_arm, Mstar, hstar, tau_m)
                for i in range(n_arm):  # actuators.clip_joint_torque
                    lim = effort[i]
                    if abs(tau_m[i]) > lim * (1 + 1e-12):
                        sat = True
                    tau_m[i] = min(max(tau_m[i], -lim), lim)
            for i in range(n_arm):  # the true joints
                tr_arm[k, ARM_ERR * n_arm + i] = ref_q[i] - q[arm_q[i]]
                tr_arm[k, ARM_REF * n_arm + i] = ref_q[i]
                tr_arm[k, ARM_RATE_REF * n_arm + i] = ref_qd[i]
                tr_arm[k, ARM_RATE * n_arm + i] = v[arm_v[i]]
                tr_arm[k, ARM_TORQUE * n_arm + i] = tau_m[i]
                tr_arm[k, ARM_STOP_TIME * n_arm + i] = 0.0
            for j in range(ns):  # at the tick's state; with stops: the largest over its steps (below)
                x = q[sj_q[j]]
                tr_arm[k, ARM_STOP_PEN * n_arm + sj_arm[j]] = max(0.0, max(x - sj_upper[j], sj_lower[j] - x))
            # base motion (base_motion.base_kinematics): base origin, m_0 R (v + ω × c)
            quat_to_matrix(q[3], q[4], q[5], q[6], Rb)
            vc0 = v[0] + v[4] * com[0, 2] - v[5] * com[0, 1]
            vc1 = v[1] + v[5] * com[0, 0] - v[3] * com[0, 2]
            vc2 = v[2] + v[3] * com[0, 1] - v[4] * com[0, 0]
            o = ARM_BLOCKS * n_arm
            for a in range(3):
                tr_arm[k, o + a] = q[a]
                tr_arm[k, o + 3 + a] = mass[0] * (Rb[a, 0] * vc0 + Rb[a, 1] * vc1 + Rb[a, 2] * vc2)
        # trace (state at the tick)
        for a in range(4):
            tr_x[k, X_REF + a] = q_ref[a]
        tr_x[k, X_EE_ERR] = ee_err
        for a in range(6):
            tr_x[k, X_REACTION + a] = math.nan
        if held:  # the support's wrench under the tick's wheel and arm torques
            mass_matrix(parent, kind, axis, inertia, armature, idx_v, R_t, p_t, M_full)
            bias_forces(parent, kind, axis, inertia, idx_v, R_t, p_t, v, n_full)
            for i in range(nw):
                tau_h[wheel_v[i]] = tau_w[i]
            for i in range(n_arm):
                tau_h[arm_v[i]] = tau_m[i]
            held_base_reaction(M_full, n_full, tau_h, react)
            for a in range(6):
                tr_x[k, X_REACTION + a] = react[a]
        tr_t[k] = t
        tr_err[k] = error_angle(q[3:7], q_ref)
        for i in range(nw):
            tr_ws[k, i] = ws[i]
            tr_tw[k, i] = tau_w[i]
        tr_sat[k] = sat
        for a in range(3):
            tr_bt[k, a] = T[a]
        for a in range(3):
            tr_mom[k, a] = me_t[a]
            tr_mom[k, 3 + a] = me_t[6 + a]
        tr_energy[k] = me_t[9]
        peak = 0.0
        for i in range(ne):
            peak = max(peak, abs(eta[i]))
        tr_modal[k] = peak
        if nw and tick % 10 == 0:
            effective_wheel_inertia(parent, kind, axis, place_R, place_p, inertia, leaf_IA, armature, idx_q, idx_v, q, wheel_v,
                                    eff_inertia, work)
        tau[:] = 0.0
        if mom_on:
            for a in range(6):
                tau[a] = wrench[a]
        elif law_on and thrusters:
            for a in range(3):
                tau[3 + a] = T[a]
        if thr_on:  # the thrusters deliver the wrench (ThrusterDrive.command by the caller), not the ideal source
            if thr_probe:
                for a in range(6):
                    thr_cmd[a] = tau[a]
                return k, steps, ALLOCATE
            for a in range(6):
                tau[a] = 0.0
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
            if dist.shape[0]:  # the base wrench of the tick plus the disturbances at the step's start
                disturbance_wrench(dist, t, q, dw)
                for a in range(6):
                    tau[a] = (T[a - 3] if (a >= 3 and law_on and thrusters) else 0.0) + dw[a]
            if thr_on:
                if thr is not None:
                    thruster_step(tree_t, thr, thr_t0, thr_on_times, q, v, tau, t, dt, q_new, v_new, impulse, thr_state, work)
            elif stop_on:
                if not stop_step(tree_a, sj_v, sj_q, sj_lower, sj_upper, restitution, sj_side, sj_rebound, sj_since, q, v,
                                 tau, dt, t, q_new, v_new, on_time, pen_max, ev, ev_n, work, modal, eta, etadot, eta_new,
                                 etadot_new, held):
                    return k + 1, steps, STOP_FAILED
            else:
                rkmk4_step(parent, kind, axis, place_R, place_p, inertia, leaf_IA, armature, idx_q, idx_v, modal_Bt, modal_BtB,
                           neg_omega2, neg_2zo, no_i, no_i, no_e, no_e, no_e, q, v, eta, etadot, tau, dt, q_new, v_new, eta_new,
                           etadot_new, work, base_lock)  # empty unless the base is held: stop_step's signature, one compilation
            t += dt
            st_t[steps] = t
            for a in range(nq):  # element loops, not slice assignment: no broadcast check to compile
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
            if thr is not None:
                n_thr = impulse.shape[0]
                for i in range(n_thr):
                    st_thr[steps, i] = impulse[i] / dt
                st_thr[steps, n_thr] = thr_state[USED]
                joint_transforms(kind, axis, place_R, place_p, idx_q, q, R_rel, p_rel)
                momenta_energy(parent, kind, axis, inertia, mass, com, armature, idx_v, R_rel, p_rel, v, me, work)
                for a in range(6):
                    st_mom[steps, a] = me[a]
                if nw:  # μ at the mass of the step's end (/momentum/locked)
                    mass_matrix(parent, kind, axis, inertia, armature, idx_v, R_rel, p_rel, M_mom)
                    model_t = locked_model(M_mom, wheel_v)
                    locked_velocity(v, model_t, st_mom[steps, 6:9])
                    if mom_model is not None:
                        if mom_vary:
                            law_model = model_t
            if mom_model is not None:
                if mom_code > 0:
                    mom_W[0] = lyapunov_terms(mom_code, q, v, q_ref, law_model, mom_par, mom_mem, st_lyap[steps])
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


@njit(**JIT)
def sample_outputs(parent, kind, axis, place_R, place_p, inertia, leaf_IA, mass, com, armature, idx_q, idx_v,
                   f_joint, f_R, f_p, f_parent, qs, vs, poses, rel, mom):
    """For each sampled state (rows of qs, vs): world poses of the recorded frames
    (poses[s, k] = [x y z qx qy qz qw]), their poses in their parent frames (rows f_parent,
    −1: world) and [p, k about the CoM, k about the origin, energy]."""
    n = parent.shape[0]
    ws = workspace(n, qs.shape[1], vs.shape[1], 0)
    R_rel = np.empty((n, 3, 3))
    p_rel = np.empty((n, 3))
    oR = np.empty((n, 3, 3))
    op = np.empty((n, 3))
    for s in range(qs.shape[0]):
        joint_transforms(kind, axis, place_R, place_p, idx_q, qs[s], R_rel, p_rel)
        world_placements(parent, R_rel, p_rel, oR, op)
        frame_poses(oR, op, f_joint, f_R, f_p, poses[s])
        relative_poses(poses[s], f_parent, rel[s])
        momenta_energy(parent, kind, axis, inertia, mass, com, armature, idx_v, R_rel, p_rel, vs[s], mom[s], ws)
