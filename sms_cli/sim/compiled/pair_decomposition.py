"""Compiled locked/shape decomposition of two spacecraft (Vicariotto 2023 §5.3-5.4): the one implementation of the
formulas in ``sms_cli.formation.decomposition``'s module docstring, which wraps these kernels.

Frames and units (SI): twists linear first ``[v; ω]``, wrenches ``[f; τ]`` (Pinocchio order). M1 (frame 1) and
M2 (frame 2) are the 6×6 locked spatial inertias (kg, kg m, kg m²) about each base-frame origin in base axes;
g12 = (R, p) = g1⁻¹ g2 (frame 1 <- frame 2, p in m); Ad⁻¹ = Ad_{g12}⁻¹ maps frame-1 twists to frame 2. Every
input array is float64 and C-contiguous (the wrappers make them so: one compiled signature per kernel).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from sms_cli.sim.compiled import JIT
from sms_cli.sim.compiled.dynamics import cholesky_solve, cholesky_solve_columns


@njit(**JIT)
def _add_skew(x, y, z, k, out, r0, c0):
    """out[r0:r0+3, c0:c0+3] += k [(x, y, z)]× (the cross-product matrix)."""
    out[r0, c0 + 1] -= k * z
    out[r0, c0 + 2] += k * y
    out[r0 + 1, c0] += k * z
    out[r0 + 1, c0 + 2] -= k * x
    out[r0 + 2, c0] -= k * y
    out[r0 + 2, c0 + 1] += k * x


@njit(**JIT)
def ad_matrix(xi, out):
    """out (6×6) = ad_ξ of the twist ξ = [v; ω]: [[ω×, v×], [0, ω×]] (Vicariotto 2023 (3.3), Pinocchio's
    ``Motion.action``)."""
    out[:, :] = 0.0
    _add_skew(xi[3], xi[4], xi[5], 1.0, out, 0, 0)
    _add_skew(xi[3], xi[4], xi[5], 1.0, out, 3, 3)
    _add_skew(xi[0], xi[1], xi[2], 1.0, out, 0, 3)


@njit(**JIT)
def ad_inverse(R, p, out):
    """out (6×6) = Ad_{(R, p)}⁻¹ = [[Rᵀ, −Rᵀ[p]×], [0, Rᵀ]] (twists of the parent frame -> the pose's frame)."""
    out[:, :] = 0.0
    for i in range(3):
        for j in range(3):
            out[i, j] = out[3 + i, 3 + j] = R[j, i]
    for i in range(3):  # −Rᵀ[p]×: row i = −(column i of R)ᵀ [p]× = (p × R[:, i])ᵀ
        r0, r1, r2 = R[0, i], R[1, i], R[2, i]
        out[i, 3] = p[1] * r2 - p[2] * r1
        out[i, 4] = p[2] * r0 - p[0] * r2
        out[i, 5] = p[0] * r1 - p[1] * r0


@njit(**JIT)
def _spd_solve(A, B):
    """A⁻¹ B for a symmetric positive definite 6×6 A (Cholesky, read on its lower triangle) and a 6×k B."""
    out = np.ascontiguousarray(B).copy()
    cholesky_solve_columns(A, 6, out, np.zeros((6, 6)), np.empty(6))
    return out


@njit(**JIT)
def _sym(A):
    """½(A + Aᵀ) in place; returns A."""
    n = A.shape[0]
    for i in range(n):
        for j in range(i + 1, n):
            A[i, j] = A[j, i] = 0.5 * (A[i, j] + A[j, i])
    return A


@njit(**JIT)
def pair_decompose(M1, M2, R, p):
    """(Ad⁻¹, M_tot, A*, S, S⁻¹, M_E) at g12 = (R, p):
    M_tot = M1 + Ad⁻ᵀ M2 Ad⁻¹ (frame 1, symmetrised), A* = M_tot⁻¹ Ad⁻ᵀ M2 (5.5),
    S = [[1 − A* Ad⁻¹, A*], [−Ad⁻¹, 1]] (5.6) and S⁻¹ = [[1, −A*], [Ad⁻¹, 1 − Ad⁻¹ A*]] (12×12 on [ξ1; ξ2]),
    M_E = (M2⁻¹ + Ad⁻¹ M1⁻¹ Ad⁻ᵀ)⁻¹ (frame 2, symmetrised)."""
    Ai = np.empty((6, 6))
    ad_inverse(R, p, Ai)
    AiT = np.ascontiguousarray(Ai.T)
    AiT_M2 = AiT @ M2
    M_tot = _sym(M1 + AiT_M2 @ Ai)
    A = _spd_solve(M_tot, AiT_M2)
    AAi, AiA = A @ Ai, Ai @ A
    S = np.zeros((12, 12))
    S_inv = np.zeros((12, 12))
    for i in range(6):
        for j in range(6):
            S[i, j] = -AAi[i, j]
            S[i, 6 + j] = A[i, j]
            S[6 + i, j] = -Ai[i, j]
            S_inv[i, 6 + j] = -A[i, j]
            S_inv[6 + i, j] = Ai[i, j]
            S_inv[6 + i, 6 + j] = -AiA[i, j]
        S[i, i] += 1.0
        S[6 + i, 6 + i] = 1.0
        S_inv[i, i] = 1.0
        S_inv[6 + i, 6 + i] += 1.0
    X = _sym(_spd_solve(M2, np.eye(6)) + Ai @ _spd_solve(M1, AiT))  # M2⁻¹ + Ad⁻¹ M1⁻¹ Ad⁻ᵀ
    M_E = _sym(_spd_solve(X, np.eye(6)))
    return Ai, M_tot, A, S, S_inv, M_E


@njit(**JIT)
def rigid_coriolis(M, xi):
    """Skew-symmetric Euler–Poincaré Coriolis matrix C(ξ) (6×6, body frame) of a rigid body of spatial inertia M:
    C = ½(M ad_ξ − ad_ξᵀ M) − ½ H̄(Mξ), H̄([f; n]) = [[0, [f]×], [[f]×, [n]×]]; C ξ = −ad_ξᵀ M ξ and C + Cᵀ = 0."""
    a = np.empty((6, 6))
    ad_matrix(xi, a)
    h = M @ xi
    C = 0.5 * (M @ a - a.T @ M)
    _add_skew(h[0], h[1], h[2], -0.5, C, 0, 3)
    _add_skew(h[0], h[1], h[2], -0.5, C, 3, 0)
    _add_skew(h[3], h[4], h[5], -0.5, C, 3, 3)
    return C


@njit(**JIT)
def s_inv_rate(M2, Ai, M_tot, A, V12, M1_dot, M2_dot):
    """d/dt S⁻¹ (12×12) given V12 (6, body twist of g12, frame 2) and the rates Ṁ1, Ṁ2 of the locked inertias:
    d/dt Ad⁻¹ = −ad_{V12} Ad⁻¹; Ṁ_tot = Ṁ1 + Ad⁻ᵀ(Ṁ2 − ad_{V12}ᵀ M2 − M2 ad_{V12}) Ad⁻¹ (L970);
    Ȧ* = M_tot⁻¹(Ad⁻ᵀ(Ṁ2 − ad_{V12}ᵀ M2) − Ṁ_tot A*) (L966)."""
    a = np.empty((6, 6))
    ad_matrix(V12, a)
    aT_M2 = a.T @ M2
    Ai_dot = -(a @ Ai)
    AiT = np.ascontiguousarray(Ai.T)
    Mtot_dot = M1_dot + AiT @ (M2_dot - aT_M2 - M2 @ a) @ Ai
    A_dot = _spd_solve(M_tot, AiT @ (M2_dot - aT_M2) - Mtot_dot @ A)
    EE = -(Ai_dot @ A) - Ai @ A_dot
    out = np.zeros((12, 12))
    for i in range(6):
        for j in range(6):
            out[i, 6 + j] = -A_dot[i, j]
            out[6 + i, j] = Ai_dot[i, j]
            out[6 + i, 6 + j] = EE[i, j]
    return out


@njit(**JIT)
def pair_coriolis(M1, M2, Ai, M_tot, A, S_inv, xi1, xi2, V12):
    """C* (12×12) of (5.8) for two rigid bodies: S⁻ᵀ C12 S⁻¹ + S⁻ᵀ M12 d/dt(S⁻¹) with C12 = diag(C(M1, ξ1),
    C(M2, ξ2)) (``rigid_coriolis``), M12 = diag(M1, M2) and d/dt S⁻¹ at V12 with constant locked inertias."""
    C12 = np.zeros((12, 12))
    M12 = np.zeros((12, 12))
    C1, C2 = rigid_coriolis(M1, xi1), rigid_coriolis(M2, xi2)
    for i in range(6):
        for j in range(6):
            C12[i, j], C12[6 + i, 6 + j] = C1[i, j], C2[i, j]
            M12[i, j], M12[6 + i, 6 + j] = M1[i, j], M2[i, j]
    Z = np.zeros((6, 6))
    rate = s_inv_rate(M2, Ai, M_tot, A, V12, Z, Z)
    return S_inv.T @ (C12 @ S_inv + M12 @ rate)


@njit(**JIT)
def locked_state(M, v, b, j, nj):
    """(ξ, Λ, M_θ) of one spacecraft from the plant's mass matrix M (nv × nv) and velocity v (nv): its base rows and
    columns are b..b+6, its joints' j..j+nj. ξ = M_bb⁻¹ (M v)_b (6, its locked twist, base frame), Λ = M_bb⁻¹ M_bθ
    (6 × nj, the mechanical connection: ξ = V + Λ θ̇) and M_θ = M_θθ − M_θb Λ (nj × nj, the joints' shape inertia)."""
    Mbb = np.ascontiguousarray(M[b:b + 6, b:b + 6])
    L = np.zeros((6, 6))
    Lam = np.ascontiguousarray(M[b:b + 6, j:j + nj]).copy()
    cholesky_solve_columns(Mbb, 6, Lam, L, np.empty(6))  # L: M_bb's Cholesky factor, reused for ξ
    h = np.ascontiguousarray(M[b:b + 6, :]) @ v
    xi = np.empty(6)
    cholesky_solve(L, h, 6, xi)
    Mth = np.empty((nj, nj))
    for r in range(nj):
        for c in range(nj):
            s = M[j + r, j + c]
            for i in range(6):
                s -= M[b + i, j + r] * Lam[i, c]
            Mth[r, c] = s
    return xi, Lam, Mth
