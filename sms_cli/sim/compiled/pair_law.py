"""Compiled relative (locked/shape) law of two spacecraft (Vicariotto 2023 §5.4): the one implementation of the
per-tick arithmetic of ``sms_cli.formation.laws.RelativeLaw`` (see that module's docstring for the law) and of the
wrench maps of ``sms_cli.formation.decomposition.PairDecomposition`` (to_bodies, to_locked_shape, shape_effort).

Frames and units (SI): twists [v; ω], wrenches [f; τ]; F1 (N, N m) acts on body 1 in frame 1, F2 on body 2 in frame
2, each at its base-frame origin; F_L in frame 1, F_E in frame 2; poses (R, p) map a frame to its parent (p in m).
Inputs are float64 C-contiguous (the wrappers make them so: one compiled signature per kernel).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from sms_cli.sim.compiled import JIT
from sms_cli.sim.compiled.momentum_laws import trace_potential
from sms_cli.sim.compiled.pair_decomposition import pair_coriolis
from sms_cli.sim.compiled.se3 import log3

FREE_FLOATING, FREE_FLYING, HIERARCHICAL = 0, 1, 2  # the law (``mode``)
BOTH, MASTER, OTHER = 0, 1, 2  # who applies the shape wrench with the locked system free (``actuated``)


@njit(**JIT)
def pose_error(R, p, Rd, pd, kp_lin, kp_ang, grad, r):
    """(U, angle) of the SE(3) potential U(g; g_d) = ½ rᵀK_p r + ½ tr(K_R(1 − R_e)) (J) of the pose g = (R, p) about
    g_d = (Rd, pd), R_e = R_dᵀR, r = R_dᵀ(p − p_d) (m, into r); grad (6) = ∇U = [R_eᵀK_p r; γ] in the body frame
    (N, N m), γ from ``momentum_laws.trace_potential``; angle = |log3(R_e)| (rad)."""
    for i in range(3):
        r[i] = Rd[0, i] * (p[0] - pd[0]) + Rd[1, i] * (p[1] - pd[1]) + Rd[2, i] * (p[2] - pd[2])
    Re = Rd.T @ R
    phi = trace_potential(kp_ang, R, Rd, grad[3:6])
    U = phi
    for i in range(3):
        U += 0.5 * kp_lin[i] * r[i] * r[i]
        grad[i] = Re[0, i] * kp_lin[0] * r[0] + Re[1, i] * kp_lin[1] * r[1] + Re[2, i] * kp_lin[2] * r[2]
    w = np.empty(3)
    return U, log3(Re, w)


@njit(**JIT)
def to_bodies(S, F_L, F_E, F1, F2):
    """[F1; F2] = Sᵀ [F_L; F_E] (the power-conjugate map of [V_L; V_E] = S [ξ1; ξ2])."""
    for j in range(6):
        a, b = 0.0, 0.0
        for i in range(6):
            a += S[i, j] * F_L[i] + S[6 + i, j] * F_E[i]
            b += S[i, 6 + j] * F_L[i] + S[6 + i, 6 + j] * F_E[i]
        F1[j], F2[j] = a, b


@njit(**JIT)
def to_locked_shape(Ai, A, F1, F2, F_L, F_E):
    """[F_L; F_E] = S⁻ᵀ [F1; F2]: F_L = F1 + Ad⁻ᵀ F2 (total wrench, frame 1), F_E = F2 − A*ᵀ F_L (frame 2)."""
    for j in range(6):
        x = F1[j]
        for i in range(6):
            x += Ai[i, j] * F2[i]
        F_L[j] = x
    for j in range(6):
        x = F2[j]
        for i in range(6):
            x -= A[i, j] * F_L[i]
        F_E[j] = x


@njit(**JIT)
def shape_effort(Ai, A, F_E, actuated, F1, F2):
    """A wrench pair (F1 frame 1, F2 frame 2) that realises the shape wrench F_E (frame 2): ``actuated`` BOTH:
    F1 = −Ad⁻ᵀ F_E, F2 = F_E (F_L = 0); MASTER: F2 = 0 and A*ᵀ F1 + F_E = 0 (the F2 row of Sᵀ with F_L = F1);
    OTHER: F1 = 0 and (1 − Ad⁻¹ A*)ᵀ F2 = F_E (F_L = Ad⁻ᵀ F2)."""
    if actuated == BOTH:
        for j in range(6):
            x = 0.0
            for i in range(6):
                x -= Ai[i, j] * F_E[i]
            F1[j], F2[j] = x, F_E[j]
    elif actuated == MASTER:
        F1[:] = np.linalg.solve(np.ascontiguousarray(A.T), -F_E)
        F2[:] = 0.0
    else:
        P = np.eye(6) - Ai @ A
        F1[:] = 0.0
        F2[:] = np.linalg.solve(np.ascontiguousarray(P.T), F_E)


@njit(**JIT)
def _wheel_torques(Lam, w, kw, rates, limits, out):
    """out = clip(Λᵀ w − k_w θ̇, ±limits) (N m); returns whether any was clipped."""
    sat = False
    for k in range(Lam.shape[1]):
        x = -kw * rates[k]
        for i in range(6):
            x += Lam[i, k] * w[i]
        c = min(max(x, -limits[k]), limits[k])
        sat = sat or c != x
        out[k] = c
    return sat


@njit(**JIT)
def _quadratic(M, x):
    """½ xᵀ M x."""
    s = 0.0
    for i in range(x.size):
        for j in range(x.size):
            s += x[i] * M[i, j] * x[j]
    return 0.5 * s


@njit(**JIT)
def relative_law(mode, actuated, locked_on, shape_on, gains, kw, R1, p1, R2, p2, R1d, p1d, R12d, p12d,
                 M1, M2, Ai, M_tot, A, S, S_inv, M_E, xi1, xi2, V1, V2,
                 Lam1, rates1, limits1, Iw1, Lam2, rates2, limits2, Iw2, F, tau1, tau2, err, pos):
    """One tick of the relative law (``sms_cli.formation.laws`` docstring). ``mode``: FREE_FLOATING, FREE_FLYING or
    HIERARCHICAL; ``actuated``: BOTH, MASTER or OTHER; ``locked_on``, ``shape_on``: which subsystems are controlled;
    ``gains`` (2, 12): per subsystem (locked, shape) [K_p linear (3), K_p angular (3), K_d (6)]; ``kw`` the wheel
    damping (N m s/rad). Poses: body 1 (R1, p1), body 2 (R2, p2) in the world, setpoints g1_d = (R1d, p1d) and
    g12_d = (R12d, p12d). The decomposition's M1, M2, Ad⁻¹, M_tot, A*, S, S⁻¹, M_E (``pair_decompose``); locked
    twists ξ1, ξ2 and base twists V1, V2 (own base frames); per body the wheels' connection Λ (6 × n), rates θ̇ (n),
    torque limits (n) and inertia (n × n).
    Writes F (4, 6) = [F1; F2; F_L; F_E], the clipped wheel torques tau1, tau2, err (2, 8) = [U, angle, ∇U (6)] and
    pos (2, 3) = r of the locked and shape pose errors (left untouched for an uncontrolled subsystem);
    returns (W (J), saturated)."""
    V = S @ np.concatenate((xi1, xi2))
    V_L, V_E = V[:6], V[6:]
    gL, gE = np.zeros(6), np.zeros(6)
    U = 0.0
    if locked_on:
        u, angle = pose_error(R1, p1, R1d, p1d, gains[0, 0:3], gains[0, 3:6], gL, pos[0])
        err[0, 0], err[0, 1] = u, angle
        err[0, 2:] = gL
        U += u
    if shape_on:
        R12 = R1.T @ R2
        p12 = R1.T @ (p2 - p1)
        u, angle = pose_error(R12, p12, R12d, p12d, gains[1, 0:3], gains[1, 3:6], gE, pos[1])
        err[1, 0], err[1, 1] = u, angle
        err[1, 2:] = gE
        U += u
    F[:, :] = 0.0
    F1, F2, F_L, F_E = F[0], F[1], F[2], F[3]
    if mode != FREE_FLOATING:
        gLf, gEf = gL.copy(), gE.copy()
        if mode == HIERARCHICAL:  # the thrusters keep the translation potentials and all damping
            gLf[3:] = 0.0
            gEf[3:] = 0.0
        C = pair_coriolis(M1, M2, Ai, M_tot, A, S_inv, xi1, xi2, V2 - Ai @ V1)
        if locked_on:
            F_L[:] = -gLf - gains[0, 6:] * V_L + np.ascontiguousarray(C[:6, 6:]) @ V_E
        F_E[:] = -gEf + A.T @ gLf
        if shape_on:
            F_E[:] += -gains[1, 6:] * V_E + np.ascontiguousarray(C[6:, :6]) @ V_L
        if locked_on or actuated == BOTH:
            to_bodies(S, F_L, F_E, F1, F2)
        else:
            shape_effort(Ai, A, F_E, actuated, F1, F2)
            to_locked_shape(Ai, A, F1, F2, F_L, F_E)
    w1 = F1 + gL - Ai.T @ gE
    w2 = F2 + gE
    sat1 = _wheel_torques(Lam1, w1, kw, rates1, limits1, tau1)
    sat2 = _wheel_torques(Lam2, w2, kw, rates2, limits2, tau2)
    W = _quadratic(M_tot, V_L) + _quadratic(M_E, V_E) + _quadratic(Iw1, rates1) + _quadratic(Iw2, rates2) + U
    return W, sat1 or sat2
