"""Compiled (numba) end-effector resolved-rate tracking (Chevallard 2019, §5.4, (5.53)–(5.57)): THE
implementation of the law's joint rates, q̇_d = J*⁺ (ẋ_d + K e − J*_r Ω) (damped least squares, then
scaled to the joints' rate limits), which ``sms_cli.sim.laws.resolved_rate.ResolvedRate`` calls with
Pinocchio's Jacobians and the compiled loop with the generalized Jacobians of the compiled kinematics
(``generalized_jacobians``).

Jacobians map to the end-effector twist [ω; v] (inertial axes; v of the end-effector frame origin,
m/s), per arm rate (J_m) or wheel rate (J_r), velocity order of ``SystemModel.arm`` / ``wheels``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from sms_cli.sim.compiled import JIT
from sms_cli.sim.compiled.dynamics import cholesky, cholesky_solve
from sms_cli.sim.compiled.tree import FREE_FLYER, PRISMATIC


@njit(**JIT)
def frame_origin(oR, op, joint, f_p, p_frame):
    """The origin (world, m) of the frame at f_p in joint ``joint`` (tree index) at the world placements (oR, op)."""
    for a in range(3):
        p_frame[a] = op[joint, a] + oR[joint, a, 0] * f_p[0] + oR[joint, a, 1] * f_p[1] + oR[joint, a, 2] * f_p[2]


@njit(**JIT)
def frame_jacobian(parent, kind, axis, idx_v, oR, op, joint, f_R, f_p, p_frame, J):
    """The world-aligned Jacobian J (6 × nv, rows [ω; v]) of the frame placed (f_R, f_p) in joint ``joint``
    (tree index) at the joint world placements (oR, op) (``dynamics.world_placements``); its origin
    (world, m) into p_frame. Pinocchio's LOCAL_WORLD_ALIGNED frame Jacobian with the halves swapped."""
    nv = J.shape[1]
    frame_origin(oR, op, joint, f_p, p_frame)
    for r in range(6):
        for c in range(nv):
            J[r, c] = 0.0
    i = joint
    while i >= 0:
        d0, d1, d2 = p_frame[0] - op[i, 0], p_frame[1] - op[i, 1], p_frame[2] - op[i, 2]
        iv = idx_v[i]
        n_dof = 6 if kind[i] == FREE_FLYER else 1
        for k in range(n_dof):
            if kind[i] == FREE_FLYER:  # [v; ω] in the joint frame: unit columns
                lin = k < 3
                s0, s1, s2 = (1.0 if k % 3 == 0 else 0.0), (1.0 if k % 3 == 1 else 0.0), (1.0 if k % 3 == 2 else 0.0)
            else:
                lin = kind[i] == PRISMATIC
                s0, s1, s2 = axis[i, 0], axis[i, 1], axis[i, 2]
            u0 = oR[i, 0, 0] * s0 + oR[i, 0, 1] * s1 + oR[i, 0, 2] * s2
            u1 = oR[i, 1, 0] * s0 + oR[i, 1, 1] * s1 + oR[i, 1, 2] * s2
            u2 = oR[i, 2, 0] * s0 + oR[i, 2, 1] * s1 + oR[i, 2, 2] * s2
            c = iv + k
            if lin:
                J[3, c], J[4, c], J[5, c] = u0, u1, u2
            else:  # ω = u; the frame origin moves at u × (p − o_i)
                J[0, c], J[1, c], J[2, c] = u0, u1, u2
                J[3, c] = u1 * d2 - u2 * d1
                J[4, c] = u2 * d0 - u0 * d2
                J[5, c] = u0 * d1 - u1 * d0
        i = parent[i]


@njit(**JIT)
def generalized_jacobians(M, J, arm_v, wheel_v, Jm, Jr):
    """Kraiem 2022 (3.5)–(3.8) at zero momentum: with the base velocity v_b = −M_bb⁻¹ M_bx ẋ that keeps the
    system's momentum zero, J_mEE = J_m − J_b M_bb⁻¹ M_bm (into Jm, 6 × n_arm) and J_rEE likewise for the
    wheels (into Jr); M the rigid mass matrix (nv × nv), J the end-effector Jacobian (``frame_jacobian``),
    base coordinates 0-5 (``SystemModel.generalized_jacobians``, whose base convention cancels here)."""
    L = np.empty((6, 6))
    cholesky(M, 6, L)
    col, x = np.empty(6), np.empty(6)
    for which in range(2):
        idx = arm_v if which == 0 else wheel_v
        out = Jm if which == 0 else Jr
        for c in range(idx.shape[0]):
            for a in range(6):
                col[a] = M[a, idx[c]]
            cholesky_solve(L, col, 6, x)
            for r in range(6):
                acc = J[r, idx[c]]
                for a in range(6):
                    acc -= J[r, a] * x[a]
                out[r, c] = acc


@njit(**JIT)
def joint_rates(Jm, Jr, twist, rows0, wheel_speed, damping, threshold, max_rate, out):
    """q̇_d = J_m⁺ (twist − J_r Ω) on the rows rows0..5 of the twist [ω; v] (3: position only), into out;
    returns the damping λ². J⁺ = Σ σ_i/(σ_i² + λ²) v_i u_iᵀ with λ² = damping² (1 − (σ_min/threshold)²) when
    σ_min < threshold (> 0), else 0 (Nakamura–Hanafusa, Maciejewski–Klein); then all rates scaled down
    together so that none exceeds its max_rate."""
    m, n = 6 - rows0, Jm.shape[1]
    A = np.empty((m, n))
    x = np.empty(m)
    for r in range(m):
        acc = twist[rows0 + r]
        for c in range(Jr.shape[1]):
            acc -= Jr[rows0 + r, c] * wheel_speed[c]
        x[r] = acc
        for c in range(n):
            A[r, c] = Jm[rows0 + r, c]
    U, S, Vt = np.linalg.svd(A, full_matrices=False)
    k = S.shape[0]
    smin = S[k - 1] if k else 0.0
    lam2 = damping * damping * (1.0 - (smin / threshold) ** 2) if (threshold > 0 and smin < threshold) else 0.0
    for c in range(n):
        out[c] = 0.0
    for i in range(k):
        d = S[i] * S[i] + lam2
        if not d > 0:
            continue
        f = S[i] / d
        ux = 0.0
        for r in range(m):
            ux += U[r, i] * x[r]
        for c in range(n):
            out[c] += Vt[i, c] * f * ux
    ratio = 0.0
    for c in range(n):
        ratio = max(ratio, abs(out[c]) / max_rate[c])
    if ratio > 1.0:
        for c in range(n):
            out[c] = out[c] / ratio
    return lam2


@njit(**JIT)
def track_end_effector(parent, kind, axis, idx_v, oR, op, ee_joint, ee_R, ee_p, M, arm_v, wheel_v, v, target, velocity,
                       gain, damping, threshold, max_rate, generalized, J, Jm, Jr, qd, ee_pos):
    """One control tick of the resolved rate (position rows) in the compiled loop: the generalized Jacobians
    at the joint placements (oR, op) and mass matrix M, the error e = target − p_EE, the twist ẋ_d + K e
    (K per axis, 1/s) and ``joint_rates`` into qd; returns |e| (m); the end-effector origin into ee_pos.
    ``generalized`` False: the fixed-base Jacobian's columns instead (M unused). J (6 × nv), Jm (6 × n_arm),
    Jr (6 × n_wheels): scratch."""
    frame_jacobian(parent, kind, axis, idx_v, oR, op, ee_joint, ee_R, ee_p, ee_pos, J)
    if generalized:
        generalized_jacobians(M, J, arm_v, wheel_v, Jm, Jr)
    else:
        for r in range(6):
            for c in range(arm_v.shape[0]):
                Jm[r, c] = J[r, arm_v[c]]
            for c in range(wheel_v.shape[0]):
                Jr[r, c] = J[r, wheel_v[c]]
    twist = np.zeros(6)
    ws = np.empty(wheel_v.shape[0])
    for i in range(wheel_v.shape[0]):
        ws[i] = v[wheel_v[i]]
    err = 0.0
    for a in range(3):
        e = target[a] - ee_pos[a]
        err += e * e
        twist[3 + a] = velocity[a] + gain[a] * e
    joint_rates(Jm, Jr, twist, 3, ws, damping, threshold, max_rate, qd)
    return math.sqrt(err)
