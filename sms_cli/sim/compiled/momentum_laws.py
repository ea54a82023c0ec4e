"""Compiled (numba) momentum-based Lyapunov laws of Vicariotto 2023 ch. 3-4: THE implementation of
wheels_free_floating (with inertia shaping), free_flying, hierarchical, se3_pd and quaternion_lyapunov,
and of their Lyapunov function W and its terms. The Python loop's classes in ``sms_cli.sim.laws.momentum``
compute the locked/shape quantities with Pinocchio (``sms_cli.dynamics.locked``) and call these kernels;
they take flat arrays only, so a compiled loop can call them too (``momentum_law``, ``momentum_lyapunov``:
the dispatch by law code). Equations and conventions: the docstring of ``sms_cli.sim.laws.momentum``.

Every law kernel has the same arguments:

    law(q, v, ref, wheels, mass, com_base, Tv, I, G, J, Lam, M_theta, par, mem, tau_w, wrench)

q (nq): configuration, q[0:3] the base origin (world, m), q[3:7] the base attitude (xyzw, world ← base);
v (nv): velocity, v[0:3] the base origin's (base frame, m/s), v[3:6] ω (base frame, rad/s); ref (4,): the
phase's reference attitude (xyzw); wheels (n,) int64: the wheel rates' indices in v; mass (kg); com_base
(3,): the system CoM from the base origin (base frame, m); Tv (3, nv − 3): the CoM velocity's map
M_vv⁻¹[M_vω, M_vs] (``LockedShape.T[0:3, 3:]``, v_c = v + Tv v[3:]); I (3, 3): the locked inertia about
the CoM (kg m²); G (3, n), J (n,): the wheel axes and axial inertias; Lam (3, n): Λ = I⁻¹GJ; M_theta
(n, n): the wheels' shape inertia; par: gains (layout below, diagonal gains as vectors); mem: the law's
state between calls (layout below); tau_w (n,) out: wheel torques (N m); wrench (6,) out: the base wrench
``[f; n]`` in the base frame about the base origin (N, N m). The Lyapunov kernels
``law_lyapunov(q, ..., par, mem, out)`` write W and its terms into out (layout ``T_*``) and read mem only.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from sms_cli.sim.compiled import HOT, JIT
from sms_cli.sim.compiled.dynamics import cross as _cross

# law codes of ``momentum_law`` / ``momentum_lyapunov``
WHEELS_FREE_FLOATING, FREE_FLYING, HIERARCHICAL, SE3_PD, QUATERNION_LYAPUNOV = 1, 2, 3, 4, 5

# parameter layout (offsets into ``par``): diagonal gains as vectors
P_KP = 0          # K_p (3): the attitude stiffness (quaternion_lyapunov: k at P_K, K_p unused)
P_KD = 3          # base damping (3): K_d^b (free_flying, hierarchical), K_d on ω (se3_pd, quaternion_lyapunov)
P_KX = 6          # K_p^x (3): the CoM PD's stiffness, N/m
P_DX = 9          # K_d^x (3): its damping, N s/m
P_TRANSLATE = 12  # 1: the translation PD (3.7) acts
P_SHAPING = 13    # 1: X = sym(ΛᵀM_θ) (inertia shaping), 0: X = M_θ
P_THRESHOLD = 14  # |μ| of the hierarchical law's switch to task 2, rad/s
P_K = 15          # the quaternion law's scalar stiffness k
P_N = 16          # then the wheel damping K_d (wheels_free_floating) or K_d^w (n)

# state layout (``mem``)
M_STAGE = 0       # hierarchical task (1, 2), latched
M_TARGET_SET = 1  # 1 once the CoM target is set (given, or the CoM at the first tick)
M_TARGET = 2      # the CoM target (3), world, m
M_N = 5

# terms layout (``out`` of the Lyapunov kernels)
T_W, T_LOCKED, T_SHAPE, T_POTENTIAL, T_TRANSLATION, T_POSITION_ERROR, T_DISSIPATION, T_STAGE, T_RESIDUAL, T_ROTATION = range(10)
T_N = 10
TERM_NAMES = ("W", "locked", "shape", "potential", "translation", "position_error", "dissipation", "stage", "residual",
              "rotation")


# ---------------------------------------------------------------------------- shared arithmetic
@njit(**HOT)
def rotation_matrix(quat, R):
    """R (world ← base) of the quaternion [x, y, z, w] (Hamilton; normalised by |q|²)."""
    x, y, z, w = quat[0], quat[1], quat[2], quat[3]
    n = x * x + y * y + z * z + w * w
    s = 2.0 / n
    R[0, 0] = 1 - s * (y * y + z * z)
    R[0, 1] = s * (x * y - z * w)
    R[0, 2] = s * (x * z + y * w)
    R[1, 0] = s * (x * y + z * w)
    R[1, 1] = 1 - s * (x * x + z * z)
    R[1, 2] = s * (y * z - x * w)
    R[2, 0] = s * (x * z - y * w)
    R[2, 1] = s * (y * z + x * w)
    R[2, 2] = 1 - s * (x * x + y * y)


@njit(**JIT)
def trace_potential(kp, R, Rd, gamma):
    """Φ = ½ tr(K_p(1 − R_e)) (returned) and γ = (skew(K_p R_e))^∨ (into gamma), R_e = R_dᵀR, K_p = diag(kp)
    (Vicariotto 2023 L361, L375, (4.11)): Φ̇ = γᵀω."""
    A = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            A[i, j] = kp[i] * (Rd[0, i] * R[0, j] + Rd[1, i] * R[1, j] + Rd[2, i] * R[2, j])
    gamma[0] = 0.5 * (A[2, 1] - A[1, 2])
    gamma[1] = 0.5 * (A[0, 2] - A[2, 0])
    gamma[2] = 0.5 * (A[1, 0] - A[0, 1])
    return 0.5 * ((kp[0] - A[0, 0]) + (kp[1] - A[1, 1]) + (kp[2] - A[2, 2]))


@njit(**JIT)
def quaternion_potential(k, quat, ref, gamma):
    """Φ = k qᵀq (returned) and γ = k q₀ q (into gamma) of the error quaternion (q, q₀) = q_ref⁻¹ ⊗ q_B (xyzw;
    Vicariotto 2023 §3.3.1): Φ̇ = γᵀω."""
    ax, ay, az, aw = -ref[0], -ref[1], -ref[2], ref[3]
    bx, by, bz, bw = quat[0], quat[1], quat[2], quat[3]
    ex = aw * bx + ax * bw + ay * bz - az * by
    ey = aw * by - ax * bz + ay * bw + az * bx
    ez = aw * bz + ax * by - ay * bx + az * bw
    e0 = aw * bw - ax * bx - ay * by - az * bz
    c = k * e0
    gamma[0] = c * ex
    gamma[1] = c * ey
    gamma[2] = c * ez
    return k * (ex * ex + ey * ey + ez * ez)


@njit(**HOT)
def _mat_vec(A, x, out):
    for i in range(A.shape[0]):
        s = 0.0
        for j in range(A.shape[1]):
            s += A[i, j] * x[j]
        out[i] = s


@njit(**HOT)
def _matT_vec(A, x, out):
    for j in range(A.shape[1]):
        s = 0.0
        for i in range(A.shape[0]):
            s += A[i, j] * x[i]
        out[j] = s


@njit(**HOT)
def _quad(x, A):
    """xᵀAx."""
    s = 0.0
    for i in range(x.shape[0]):
        r = 0.0
        for j in range(x.shape[0]):
            r += A[i, j] * x[j]
        s += x[i] * r
    return s


@njit(**HOT)
def _quad_diag(x, par, at):
    """xᵀ diag(par[at:at+n]) x."""
    s = 0.0
    for i in range(x.shape[0]):
        s += x[i] * par[at + i] * x[i]
    return s


@njit(**JIT)
def shaped_inertia(Lam, M_theta, shaping, X):
    """X of the rotors' kinetic energy ½θ̇ᵀXθ̇: sym(ΛᵀM_θ) with inertia shaping (§4.2.2), else M_θ."""
    n = M_theta.shape[0]
    if not shaping:
        X[:, :] = M_theta
        return
    for i in range(n):
        for j in range(n):
            a = 0.0
            b = 0.0
            for k in range(3):
                a += Lam[k, i] * M_theta[k, j]
                b += Lam[k, j] * M_theta[k, i]
            X[i, j] = 0.5 * (a + b)


@njit(**JIT)
def locked_state(q, v, ref, wheels, Lam, par, quaternion, R, wd, mu, gamma):
    """The state quantities of every law: R (world ← base), θ̇ (wd), μ = ω + Λθ̇ (Vicariotto 2023 (4.8)),
    γ; returns Φ (the trace potential, or the quaternion one when ``quaternion``)."""
    rotation_matrix(q[3:7], R)
    for i in range(wheels.shape[0]):
        wd[i] = v[wheels[i]]
    for i in range(3):
        s = 0.0
        for j in range(wheels.shape[0]):
            s += Lam[i, j] * wd[j]
        mu[i] = v[3 + i] + s
    if quaternion:
        return quaternion_potential(par[P_K], q[3:7], ref, gamma)
    Rd = np.empty((3, 3))
    rotation_matrix(ref, Rd)
    return trace_potential(par[P_KP:P_KP + 3], R, Rd, gamma)


@njit(**JIT)
def wheel_law(Lam, M_theta, shaping, gamma, wd, par, at, out):
    """τ_w = M_θX⁻¹(Λᵀγ − K_dθ̇), K_d = diag(par[at:at+n]): (4.13) for X = M_θ (= Λᵀγ − K_dθ̇), (4.18)/§4.2.2
    for X = sym(ΛᵀM_θ)."""
    n = wd.shape[0]
    u = np.empty(n)
    _matT_vec(Lam, gamma, u)
    for i in range(n):
        u[i] = u[i] - par[at + i] * wd[i]
    if not shaping:
        out[:] = u
        return
    X = np.empty((n, n))
    shaped_inertia(Lam, M_theta, True, X)
    _mat_vec(M_theta, np.linalg.solve(X, u), out)


@njit(**JIT)
def com_state(q, v, R, com_base, Tv, c, cdot):
    """The system CoM c = p + R c_b and its velocity ċ = R(v + Tv v[3:]) (world)."""
    vc = np.empty(3)
    for i in range(3):
        s = 0.0
        for j in range(Tv.shape[1]):
            s += Tv[i, j] * v[3 + j]
        vc[i] = v[i] + s
    for i in range(3):
        c[i] = q[i] + (R[i, 0] * com_base[0] + R[i, 1] * com_base[1] + R[i, 2] * com_base[2])
        cdot[i] = R[i, 0] * vc[0] + R[i, 1] * vc[1] + R[i, 2] * vc[2]


@njit(**JIT)
def base_wrench(q, v, R, com_base, Tv, tau_c, par, mem, wrench):
    """[f; τ_c + c_b × f] (base frame, about the base origin): the CoM torque ``tau_c`` and the translation PD
    (3.7) f = Rᵀ(−K_p^xΔx − K_d^xċ) rotated into the base frame (erratum 3), Δx = c − c_d; sets the target
    c_d to the CoM on the first call without one (mem)."""
    f = np.zeros(3)
    if par[P_TRANSLATE] != 0.0:
        c, cdot = np.empty(3), np.empty(3)
        com_state(q, v, R, com_base, Tv, c, cdot)
        if mem[M_TARGET_SET] == 0.0:
            mem[M_TARGET:M_TARGET + 3] = c
            mem[M_TARGET_SET] = 1.0
        fw = np.empty(3)
        for i in range(3):
            fw[i] = -(par[P_KX + i] * (c[i] - mem[M_TARGET + i])) - par[P_DX + i] * cdot[i]
        _matT_vec(R, fw, f)
    cf = np.empty(3)
    _cross(com_base, f, cf)
    for i in range(3):
        wrench[i] = f[i]
        wrench[3 + i] = tau_c[i] + cf[i]


@njit(**JIT)
def translation_terms(q, v, R, mass, com_base, Tv, par, mem, out):
    """out[T_TRANSLATION] = ½m|ċ|² + ½ΔxᵀK_p^xΔx, out[T_POSITION_ERROR] = |Δx| (Δx = 0 before the target is
    set); returns the dissipation ċᵀK_d^xċ. All 0 without the translation PD."""
    out[T_TRANSLATION] = 0.0
    out[T_POSITION_ERROR] = 0.0
    if par[P_TRANSLATE] == 0.0:
        return 0.0
    c, cdot, dx = np.empty(3), np.empty(3), np.zeros(3)
    com_state(q, v, R, com_base, Tv, c, cdot)
    if mem[M_TARGET_SET] != 0.0:
        for i in range(3):
            dx[i] = c[i] - mem[M_TARGET + i]
    out[T_TRANSLATION] = 0.5 * mass * (cdot[0] * cdot[0] + cdot[1] * cdot[1] + cdot[2] * cdot[2]) + \
        0.5 * _quad_diag(dx, par, P_KX)
    out[T_POSITION_ERROR] = math.sqrt(dx[0] * dx[0] + dx[1] * dx[1] + dx[2] * dx[2])
    return _quad_diag(cdot, par, P_DX)


@njit(**JIT)
def _wheel_terms(I, Lam, M_theta, shaping, wd, mu, phi, out):
    """out[T_LOCKED] = ½μᵀIμ, out[T_SHAPE] = ½θ̇ᵀXθ̇, out[T_POTENTIAL] = Φ; the other terms 0."""
    out[:] = 0.0
    out[T_LOCKED] = 0.5 * _quad(mu, I)
    n = wd.shape[0]
    X = np.empty((n, n))
    shaped_inertia(Lam, M_theta, shaping, X)
    out[T_SHAPE] = 0.5 * _quad(wd, X)
    out[T_POTENTIAL] = phi


# ---------------------------------------------------------------------------- the laws
@njit(**JIT)
def wheels_free_floating(q, v, ref, wheels, mass, com_base, Tv, I, G, J, Lam, M_theta, par, mem, tau_w, wrench):
    """(4.13) τ_w = Λᵀγ − K_dθ̇; with inertia shaping (§4.2.2) τ_w = M_θ(ΛᵀM_θ)⁻¹(Λᵀγ − K_dθ̇). No wrench (0)."""
    n = wheels.shape[0]
    R, wd, mu, gamma = np.empty((3, 3)), np.empty(n), np.empty(3), np.empty(3)
    locked_state(q, v, ref, wheels, Lam, par, False, R, wd, mu, gamma)
    wheel_law(Lam, M_theta, par[P_SHAPING] != 0.0, gamma, wd, par, P_N, tau_w)
    wrench[:] = 0.0


@njit(**JIT)
def wheels_free_floating_lyapunov(q, v, ref, wheels, mass, com_base, Tv, I, G, J, Lam, M_theta, par, mem, out):
    """W (4.9) = ½μᵀIμ + ½θ̇ᵀM_θθ̇ + Φ, shaped W_θ (L768) = ½θ̇ᵀΛᵀM_θθ̇ + Φ; dissipation θ̇ᵀK_dθ̇."""
    n = wheels.shape[0]
    R, wd, mu, gamma = np.empty((3, 3)), np.empty(n), np.empty(3), np.empty(3)
    phi = locked_state(q, v, ref, wheels, Lam, par, False, R, wd, mu, gamma)
    shaping = par[P_SHAPING] != 0.0
    _wheel_terms(I, Lam, M_theta, shaping, wd, mu, phi, out)
    out[T_W] = out[T_SHAPE] + out[T_POTENTIAL] + (0.0 if shaping else out[T_LOCKED])
    out[T_DISSIPATION] = _quad_diag(wd, par, P_N)


@njit(**JIT)
def free_flying(q, v, ref, wheels, mass, com_base, Tv, I, G, J, Lam, M_theta, par, mem, tau_w, wrench):
    """(4.15) τ_c = −γ − K_d^bμ + (Iμ) × (Λθ̇), (4.16) τ_w = Λᵀτ_c + M_θX⁻¹(Λᵀγ − K_d^wθ̇) − Λᵀ(ω × Iμ), the
    translation PD (3.7) rotated into the base frame; wrench [f; τ_c + c_b × f]."""
    n = wheels.shape[0]
    R, wd, mu, gamma = np.empty((3, 3)), np.empty(n), np.empty(3), np.empty(3)
    locked_state(q, v, ref, wheels, Lam, par, False, R, wd, mu, gamma)
    Imu, Lwd, tau_c, cor = np.empty(3), np.empty(3), np.empty(3), np.empty(3)
    _mat_vec(I, mu, Imu)
    _mat_vec(Lam, wd, Lwd)
    _cross(Imu, Lwd, tau_c)
    for i in range(3):
        tau_c[i] = (-gamma[i] - par[P_KD + i] * mu[i]) + tau_c[i]
    _cross(v[3:6], Imu, cor)
    a, b, c = np.empty(n), np.empty(n), np.empty(n)
    _matT_vec(Lam, tau_c, a)
    wheel_law(Lam, M_theta, par[P_SHAPING] != 0.0, gamma, wd, par, P_N, b)
    _matT_vec(Lam, cor, c)
    for i in range(n):
        tau_w[i] = (a[i] + b[i]) - c[i]
    base_wrench(q, v, R, com_base, Tv, tau_c, par, mem, wrench)


@njit(**JIT)
def free_flying_lyapunov(q, v, ref, wheels, mass, com_base, Tv, I, G, J, Lam, M_theta, par, mem, out):
    """W = ½m|ċ|² + ½ΔxᵀK_p^xΔx + ½μᵀIμ + ½θ̇ᵀXθ̇ + Φ; dissipation ċᵀK_d^xċ + μᵀK_d^bμ + θ̇ᵀK_d^wθ̇ (4.17)."""
    n = wheels.shape[0]
    R, wd, mu, gamma = np.empty((3, 3)), np.empty(n), np.empty(3), np.empty(3)
    phi = locked_state(q, v, ref, wheels, Lam, par, False, R, wd, mu, gamma)
    _wheel_terms(I, Lam, M_theta, par[P_SHAPING] != 0.0, wd, mu, phi, out)
    diss = translation_terms(q, v, R, mass, com_base, Tv, par, mem, out)
    diss += _quad_diag(mu, par, P_KD) + _quad_diag(wd, par, P_N)
    out[T_W] = out[T_LOCKED] + out[T_SHAPE] + out[T_POTENTIAL] + out[T_TRANSLATION]
    out[T_DISSIPATION] = diss


@njit(**JIT)
def hierarchical(q, v, ref, wheels, mass, com_base, Tv, I, G, J, Lam, M_theta, par, mem, tau_w, wrench):
    """Task 1 (mem[M_STAGE] = 1): τ_c = −K_d^bμ + (Iμ) × (Λθ̇), wheels idle; from |μ| ≤ threshold on (latched),
    task 2: τ_w = M_θX⁻¹(Λᵀγ − K_d^wθ̇), no wrench (§4.2.4)."""
    n = wheels.shape[0]
    R, wd, mu, gamma = np.empty((3, 3)), np.empty(n), np.empty(3), np.empty(3)
    locked_state(q, v, ref, wheels, Lam, par, False, R, wd, mu, gamma)
    if mem[M_STAGE] == 1.0 and math.sqrt(mu[0] * mu[0] + mu[1] * mu[1] + mu[2] * mu[2]) <= par[P_THRESHOLD]:
        mem[M_STAGE] = 2.0
    wrench[:] = 0.0
    if mem[M_STAGE] == 1.0:
        Imu, Lwd, tc = np.empty(3), np.empty(3), np.empty(3)
        _mat_vec(I, mu, Imu)
        _mat_vec(Lam, wd, Lwd)
        _cross(Imu, Lwd, tc)
        for i in range(3):
            wrench[3 + i] = -(par[P_KD + i] * mu[i]) + tc[i]
        tau_w[:] = 0.0
        return
    wheel_law(Lam, M_theta, par[P_SHAPING] != 0.0, gamma, wd, par, P_N, tau_w)


@njit(**JIT)
def hierarchical_lyapunov(q, v, ref, wheels, mass, com_base, Tv, I, G, J, Lam, M_theta, par, mem, out):
    """Task 1: W_1 = ½μᵀIμ, dissipation μᵀK_d^bμ; task 2: W_2 = ½θ̇ᵀXθ̇ + Φ (L830), dissipation θ̇ᵀK_d^wθ̇ and
    the μ ≠ 0 residual power γᵀμ + θ̇ᵀXM_θ⁻¹Λᵀ(ω × Iμ)."""
    n = wheels.shape[0]
    R, wd, mu, gamma = np.empty((3, 3)), np.empty(n), np.empty(3), np.empty(3)
    phi = locked_state(q, v, ref, wheels, Lam, par, False, R, wd, mu, gamma)
    shaping = par[P_SHAPING] != 0.0
    _wheel_terms(I, Lam, M_theta, shaping, wd, mu, phi, out)
    out[T_STAGE] = mem[M_STAGE]
    if mem[M_STAGE] == 1.0:
        out[T_W] = out[T_LOCKED]
        out[T_DISSIPATION] = _quad_diag(mu, par, P_KD)
        out[T_RESIDUAL] = 0.0
        return
    out[T_W] = out[T_SHAPE] + out[T_POTENTIAL]
    out[T_DISSIPATION] = _quad_diag(wd, par, P_N)
    Imu, w_Imu, cor = np.empty(3), np.empty(3), np.empty(n)
    _mat_vec(I, mu, Imu)
    _cross(v[3:6], Imu, w_Imu)
    _matT_vec(Lam, w_Imu, cor)
    X = np.empty((n, n))
    shaped_inertia(Lam, M_theta, shaping, X)
    y = np.linalg.solve(M_theta, cor)
    out[T_RESIDUAL] = (gamma[0] * mu[0] + gamma[1] * mu[1] + gamma[2] * mu[2]) + _quad_bilinear(wd, X, y)


@njit(**HOT)
def _quad_bilinear(x, A, y):
    """xᵀAy."""
    s = 0.0
    for i in range(x.shape[0]):
        r = 0.0
        for j in range(y.shape[0]):
            r += A[i, j] * y[j]
        s += x[i] * r
    return s


@njit(**JIT)
def _rigid_pd(q, v, ref, wheels, mass, com_base, Tv, Lam, par, mem, quaternion, tau_w, wrench):
    n = wheels.shape[0]
    R, wd, mu, gamma = np.empty((3, 3)), np.empty(n), np.empty(3), np.empty(3)
    locked_state(q, v, ref, wheels, Lam, par, quaternion, R, wd, mu, gamma)
    tau_c = np.empty(3)
    for i in range(3):
        tau_c[i] = -gamma[i] - par[P_KD + i] * v[3 + i]
    tau_w[:] = 0.0
    base_wrench(q, v, R, com_base, Tv, tau_c, par, mem, wrench)


@njit(**JIT)
def _rigid_pd_lyapunov(q, v, ref, wheels, mass, com_base, Tv, I, G, J, Lam, par, mem, quaternion, out):
    n = wheels.shape[0]
    R, wd, mu, gamma = np.empty((3, 3)), np.empty(n), np.empty(3), np.empty(3)
    phi = locked_state(q, v, ref, wheels, Lam, par, quaternion, R, wd, mu, gamma)
    out[:] = 0.0
    Ib = np.empty((3, 3))  # I − GJGᵀ: without the rotors' axial inertia
    for i in range(3):
        for j in range(3):
            s = 0.0
            for k in range(n):
                s += (G[i, k] * J[k]) * G[j, k]
            Ib[i, j] = I[i, j] - s
    out[T_ROTATION] = 0.5 * _quad(v[3:6], Ib)
    out[T_POTENTIAL] = phi
    diss = translation_terms(q, v, R, mass, com_base, Tv, par, mem, out)
    diss += _quad_diag(v[3:6], par, P_KD)
    out[T_W] = out[T_ROTATION] + out[T_POTENTIAL] + out[T_TRANSLATION]
    out[T_DISSIPATION] = diss


@njit(**JIT)
def se3_pd(q, v, ref, wheels, mass, com_base, Tv, I, G, J, Lam, M_theta, par, mem, tau_w, wrench):
    """The Bullo-Murray PD (3.7)/(3.9): τ_c = −γ − K_dω (erratum 4), the translation PD rotated into the base
    frame, wheels idle (0)."""
    _rigid_pd(q, v, ref, wheels, mass, com_base, Tv, Lam, par, mem, False, tau_w, wrench)


@njit(**JIT)
def se3_pd_lyapunov(q, v, ref, wheels, mass, com_base, Tv, I, G, J, Lam, M_theta, par, mem, out):
    """W (L449) = ½m|ċ|² + ½ωᵀ(I − GJGᵀ)ω + ½ΔxᵀK_p^xΔx + Φ; dissipation ċᵀK_d^xċ + ωᵀK_dω (3.15)."""
    _rigid_pd_lyapunov(q, v, ref, wheels, mass, com_base, Tv, I, G, J, Lam, par, mem, False, out)


@njit(**JIT)
def quaternion_lyapunov(q, v, ref, wheels, mass, com_base, Tv, I, G, J, Lam, M_theta, par, mem, tau_w, wrench):
    """§3.3.1: τ_c = −k q₀q − K_dω on q_ref⁻¹ ⊗ q, the translation PD as se3_pd, wheels idle (0)."""
    _rigid_pd(q, v, ref, wheels, mass, com_base, Tv, Lam, par, mem, True, tau_w, wrench)


@njit(**JIT)
def quaternion_lyapunov_lyapunov(q, v, ref, wheels, mass, com_base, Tv, I, G, J, Lam, M_theta, par, mem, out):
    """W = ½ωᵀ(I − GJGᵀ)ω + k qᵀq (+ the translation terms); dissipation ωᵀK_dω (+ ċᵀK_d^xċ)."""
    _rigid_pd_lyapunov(q, v, ref, wheels, mass, com_base, Tv, I, G, J, Lam, par, mem, True, out)


# ---------------------------------------------------------------------------- dispatch (for a compiled loop)
@njit(**JIT)
def momentum_law(code, q, v, ref, wheels, mass, com_base, Tv, I, G, J, Lam, M_theta, par, mem, tau_w, wrench):
    """The law of ``code`` (WHEELS_FREE_FLOATING … QUATERNION_LYAPUNOV)."""
    if code == WHEELS_FREE_FLOATING:
        wheels_free_floating(q, v, ref, wheels, mass, com_base, Tv, I, G, J, Lam, M_theta, par, mem, tau_w, wrench)
    elif code == FREE_FLYING:
        free_flying(q, v, ref, wheels, mass, com_base, Tv, I, G, J, Lam, M_theta, par, mem, tau_w, wrench)
    elif code == HIERARCHICAL:
        hierarchical(q, v, ref, wheels, mass, com_base, Tv, I, G, J, Lam, M_theta, par, mem, tau_w, wrench)
    elif code == SE3_PD:
        se3_pd(q, v, ref, wheels, mass, com_base, Tv, I, G, J, Lam, M_theta, par, mem, tau_w, wrench)
    else:
        quaternion_lyapunov(q, v, ref, wheels, mass, com_base, Tv, I, G, J, Lam, M_theta, par, mem, tau_w, wrench)


@njit(**JIT)
def momentum_lyapunov(code, q, v, ref, wheels, mass, com_base, Tv, I, G, J, Lam, M_theta, par, mem, out):
    """W and its terms of the law of ``code`` into out (layout T_*)."""
    if code == WHEELS_FREE_FLOATING:
        wheels_free_floating_lyapunov(q, v, ref, wheels, mass, com_base, Tv, I, G, J, Lam, M_theta, par, mem, out)
    elif code == FREE_FLYING:
        free_flying_lyapunov(q, v, ref, wheels, mass, com_base, Tv, I, G, J, Lam, M_theta, par, mem, out)
    elif code == HIERARCHICAL:
        hierarchical_lyapunov(q, v, ref, wheels, mass, com_base, Tv, I, G, J, Lam, M_theta, par, mem, out)
    elif code == SE3_PD:
        se3_pd_lyapunov(q, v, ref, wheels, mass, com_base, Tv, I, G, J, Lam, M_theta, par, mem, out)
    else:
        quaternion_lyapunov_lyapunov(q, v, ref, wheels, mass, com_base, Tv, I, G, J, Lam, M_theta, par, mem, out)
