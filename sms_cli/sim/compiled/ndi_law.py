"""Kraiem 2022 NDI + observer law (§3.3–3.4) in numba: THE implementation, which the Python loop's
``sms_cli.sim.laws.ndi.NdiObserver`` and the compiled loop both call.

Coordinates are the SystemModel's augmented velocity x = [v; η̇] (nx): index sets ``lin`` (base
linear, 3), ``ang`` (base angular ω0, 3, base frame), ``act`` (wheels then arm joints) and ``flex``
(spring joints then modal coordinates). The observer state is x_e = [f; ω0; ḟ] (n_e = 2 n_f + 3).
Units SI (rad, m, sqrt(kg) m for η).

- ``reduced_at_rest``: the reduced model linearised at rest (Routh reduction of the base translation,
  observer matrices (3.28)–(3.30), actuator dynamics (3.33)–(3.35)); ``sms_cli.model.reduced`` and the
  synthesis use it too.
- ``ndi_velocity``, ``actuator_dynamics``, ``ndi_command``: the estimated velocity, the actuators' reduced
  dynamics and the actuator torques (wheels then arm) of one control period; the caller evaluates the bias
  and internal forces r in between. One solve per tick: ``reduced_bias`` gives n of another r from it.
- ``rigid_velocity``, ``torque_split``: the torques' feedback, linearising and disturbance parts.
- ``ndi_observe``: the exact ZOH propagation of the observer over the period (discretisation refreshed
  when the arm moved by more than ``refresh`` or the model changed).
- ``ndo_estimate``, ``ndo_refresh``: the disturbance observer of Kraiem 2022 ch. 4 (4.12), its estimate τ̂_d
  at a tick and its discretisation over the period that follows; the law subtracts τ̂_d from the torques
  (4.21) by handing ``ndi_command`` n − τ̂_d.
- ``augmented_mass``, ``augmented_bias``: M (nx×nx) and r = bias − internal forces for base-mounted
  appendages (the compiled loop's counterparts of ``SystemModel.mass_matrix``, ``bias_forces`` −
  ``internal_forces``).
"""

from __future__ import annotations

import cmath
import math

import numpy as np
from numba import njit, types

from sms_cli.sim.compiled import JIT
from sms_cli.sim.compiled.control import error_quaternion
from sms_cli.sim.compiled.dynamics import bias_forces, cholesky, cholesky_solve, mass_matrix, quat_to_matrix

# flags of the law's state (int64 array)
STARTED, DISC_VALID, PINV_VALID, SATURATED, NDO_PENDING, N_FLAGS = 0, 1, 2, 3, 4, 5


@njit(**JIT)
def _sub(M, rows, cols):
    out = np.empty((rows.shape[0], cols.shape[0]))
    for i in range(rows.shape[0]):
        for j in range(cols.shape[0]):
            out[i, j] = M[rows[i], cols[j]]
    return out


@njit(**JIT)
def reduced_at_rest(M, lin, ang, act, flex, K_f, C_f, A_e, B_tau, M_dia, D_x, B_eps):
    """The Kraiem 2022 reduced matrices at rest from the augmented mass matrix M (nx×nx) and the
    flexible stiffness K_f and damping C_f (n_f×n_f): A_e (n_e×n_e) of x_e = [f; ω0; ḟ], the observer's
    input matrix B_τ (n_e×n_q, rows [ω0; ḟ] = −M*⁻¹ M_bq M_qq⁻¹), M◇ (n_q×n_q, symmetrised),
    D◇_x (n_q×n_e) and B_ε = M◇⁻¹ D◇_x. The base translation is first eliminated at constant linear
    momentum (Schur complement on the kept coordinates [ω0; q; f])."""
    n_w, n_q, n_f = ang.shape[0], act.shape[0], flex.shape[0]
    nk = n_w + n_q + n_f
    keep = np.empty(nk, dtype=np.int64)
    keep[:n_w] = ang
    keep[n_w:n_w + n_q] = act
    keep[n_w + n_q:] = flex
    Mk = _sub(M, keep, keep)
    if lin.shape[0]:
        Mkl = _sub(M, keep, lin)
        Mk = Mk - Mkl @ np.linalg.solve(_sub(M, lin, lin), Mkl.T)
    b = np.empty(n_w + n_f, dtype=np.int64)  # [ω0; f] inside Mk
    for i in range(n_w):
        b[i] = i
    for i in range(n_f):
        b[n_w + i] = n_w + n_q + i
    a = np.arange(n_q) + n_w
    Mbb, Mbq, Mqq = _sub(Mk, b, b), _sub(Mk, b, a), _sub(Mk, a, a)
    n_e = 2 * n_f + n_w
    # generalized force on b per unit of x_e: F_b = S x_e, S = [[0, 0, 0], [K_f, 0, C_f]]
    S = np.zeros((n_w + n_f, n_e))
    for i in range(n_f):
        for j in range(n_f):
            S[n_w + i, j] = K_f[i, j]
            S[n_w + i, n_f + n_w + j] = C_f[i, j]
    Mstar = Mbb - Mbq @ np.linalg.solve(Mqq, Mbq.T)
    A_e[:, :] = 0.0
    for i in range(n_f):
        A_e[i, n_f + n_w + i] = 1.0
    A_e[n_f:, :] = -np.linalg.solve(Mstar, S)
    B_tau[:, :] = 0.0
    B_tau[n_f:, :] = -np.linalg.solve(Mstar, Mbq @ np.linalg.inv(Mqq))
    Md = Mqq - Mbq.T @ np.linalg.solve(Mbb, Mbq)
    D_x[:, :] = -Mbq.T @ np.linalg.solve(Mbb, S)
    B_eps[:, :] = np.linalg.solve(Md, D_x)
    M_dia[:, :] = (Md + Md.T) / 2


@njit(**JIT)
def _norm_1(A):
    """‖A‖₁: the largest column sum of |A|."""
    best = 0.0
    for j in range(A.shape[1]):
        c = 0.0
        for i in range(A.shape[0]):
            c += abs(A[i, j])
        best = max(best, c)
    return best


@njit(**JIT)
def _expm(A):
    """e^A by scaling and squaring of the diagonal Padé (6, 6) approximant (‖A/2^s‖₁ ≤ 1/2)."""
    n = A.shape[0]
    norm = _norm_1(A)
    s = 0
    if norm > 0.5:
        s = int(math.ceil(math.log2(norm / 0.5)))
    X = A / 2.0**s
    N = np.eye(n)
    D = np.eye(n)
    P = np.eye(n)
    c = 1.0
    q = 6
    for k in range(1, q + 1):
        c = c * (q - k + 1) / (k * (2 * q - k + 1))
        P = P @ X
        N = N + c * P
        D = D + (-1.0) ** k * c * P
    E = np.linalg.solve(D, N)
    for _ in range(s):
        E = E @ E
    return E


# LAPACK's dgeev as numba's own eig calls it (by symbol name, so the callers stay cacheable). numba's eig of a real
# matrix refuses complex eigenvalues and its complex path (zgeev on A as complex, then complex inverses) costs 2-3x
# more to run. The binding is numba's private API: a numba without it discretises by
# the Padé exponential (``_discretise_by_expm``), same results to round-off.
try:
    from numba.np.linalg import _LAPACK

    _rgeev = _LAPACK().numba_ez_rgeev(types.float64)
except (ImportError, AttributeError):  # pragma: no cover - numba 0.68 has it
    _rgeev = None


@njit(**JIT)
def _lapack_real_blocks(A):
    """(ok, W, re, im): the real eigen-decomposition A W = W Λ of the real n×n A by LAPACK's dgeev, Λ
    block-diagonal with re[j] on the diagonal and, for a conjugate pair re ± i·im in columns (j, j + 1) (im[j] > 0,
    im[j + 1] = −im[j]), Λ[j, j + 1] = im[j], Λ[j + 1, j] = −im[j]: the pair's eigenvectors are x ± iy with x, y
    the columns j, j + 1 of W. The columns are √2·(x, y) for a pair and the unit eigenvector for a real eigenvalue, so
    cond(W) (2-norm) equals the condition number of the unit-norm complex eigenvector matrix. ok is False when
    dgeev fails."""
    n = A.shape[0]
    a = np.ascontiguousarray(A.T)  # column-major A (overwritten)
    wr, wi, vr, vl = np.empty(n), np.empty(n), np.empty((n, n)), np.empty((1, 1))  # vr[j]: eigenvector column j
    W = np.empty((n, n))
    if _rgeev(ord("d"), ord("N"), ord("V"), n, a.ctypes, n, wr.ctypes, wi.ctypes, vl.ctypes, 1, vr.ctypes, n) != 0:
        return False, W, wr, wi
    j = 0
    while j < n:
        if wi[j] == 0.0 or j == n - 1:
            for i in range(n):
                W[i, j] = vr[j, i]
            j += 1
        else:  # a conjugate pair: vr[j] ± i vr[j + 1]
            for i in range(n):
                W[i, j], W[i, j + 1] = math.sqrt(2.0) * vr[j, i], math.sqrt(2.0) * vr[j + 1, i]
            j += 2
    return True, W, wr, wi


@njit(**JIT)
def _no_real_blocks(A):
    """``_lapack_real_blocks`` on a numba without the dgeev binding: never ok (the Padé path runs instead)."""
    n = A.shape[0]
    return False, np.empty((n, n)), np.empty(n), np.empty(n)


real_blocks = _lapack_real_blocks if _rgeev is not None else _no_real_blocks


@njit(**JIT)
def _discretise_by_expm(A_L, T, Phi, Gamma):
    """Φ = e^{A_L T}, Γ = ∫₀ᵀ e^{A_L s} ds as the blocks of the exponential of [[A_L, I], [0, 0]] T."""
    n = A_L.shape[0]
    aug = np.zeros((2 * n, 2 * n))
    aug[:n, :n] = A_L * T
    for i in range(n):
        aug[i, n + i] = T
    E = _expm(aug)
    Phi[:, :] = E[:n, :n]
    Gamma[:, :] = E[:n, n:]


@njit(**JIT)
def observer_discretisation(A_L, T, Phi, Gamma):
    """Φ = e^{A_L T}, Γ = ∫₀ᵀ e^{A_L s} ds (n_e×n_e): by the real eigen-decomposition A_L = W Λ W⁻¹
    (``real_blocks``) when it is well conditioned (‖W‖₁‖W⁻¹‖₁ < 1e8) and has no zero eigenvalue — per block, e^{λT}
    and (e^{λT} − 1)/λ, a pair a ± ib giving e^{aT}[[cos bT, sin bT], [−sin bT, cos bT]] and the same form of
    (e^{zT} − 1)/z, z = a + ib — else by the exponential of [[A_L, I], [0, 0]] T. The 1-norm condition number comes
    from the inverse the decomposition needs anyway (the 2-norm one, an SVD, cost a quarter of the refresh)."""
    n = A_L.shape[0]
    ok, W, re, im = real_blocks(A_L)
    min_abs = np.inf
    for i in range(n):
        min_abs = min(min_abs, math.hypot(re[i], im[i]))
    Wi = np.empty((n, n))
    cond = np.inf
    if ok and n and min_abs > 1e-12:
        try:
            Wi[:, :] = np.linalg.inv(W)
            cond = _norm_1(W) * _norm_1(Wi)
        except Exception:  # noqa: BLE001 - an exactly singular W: the Padé path
            cond = np.inf
    if not cond < 1e8:
        _discretise_by_expm(A_L, T, Phi, Gamma)
        return
    E, G = np.zeros((n, n)), np.zeros((n, n))
    j = 0
    while j < n:
        if im[j] == 0.0 or j == n - 1:
            e = math.exp(re[j] * T)
            E[j, j], G[j, j] = e, (e - 1.0) / re[j]
            j += 1
        else:
            z = complex(re[j], im[j])
            ez = cmath.exp(z * T)
            g = (ez - 1.0) / z
            E[j, j], E[j, j + 1], E[j + 1, j], E[j + 1, j + 1] = ez.real, ez.imag, -ez.imag, ez.real
            G[j, j], G[j, j + 1], G[j + 1, j], G[j + 1, j + 1] = g.real, g.imag, -g.imag, g.real
            j += 2
    Phi[:, :] = W @ E @ Wi
    Gamma[:, :] = W @ G @ Wi


@njit(**JIT)
def _zero_momentum_velocity(M, lin, ang, act, flex, omega, v, fdot, x):
    """x = [v_lin; ω0; q̇_a; ḟ] (nx): ω0 = omega, q̇_a from v (nv), ḟ = fdot, v_lin from zero linear momentum."""
    x[:] = 0.0
    for a in range(ang.shape[0]):
        x[ang[a]] = omega[a]
    for i in range(act.shape[0]):
        x[act[i]] = v[act[i]]
    for i in range(flex.shape[0]):
        x[flex[i]] = fdot[i]
    rhs = _sub(M, lin, np.arange(M.shape[0])) @ x
    sol = np.linalg.solve(_sub(M, lin, lin), rhs)
    for a in range(lin.shape[0]):
        x[lin[a]] = -sol[a]


@njit(**JIT)
def ndi_velocity(M, lin, ang, act, flex, omega, v, x_hat, flags, x):
    """x̂ = [v_lin; ω0; q̇_a; ḟ̂] (nx) into x: ω0 and q̇_a measured (v: the velocity, nv), ḟ̂ from the
    observer, v_lin from zero linear momentum. The first call seeds the observer's ω0 with the gyro."""
    n_f = flex.shape[0]
    if flags[STARTED] == 0:
        for a in range(3):
            x_hat[n_f + a] = omega[a]
        flags[STARTED] = 1
    _zero_momentum_velocity(M, lin, ang, act, flex, omega, v, x_hat[n_f + 3:], x)


@njit(**JIT)
def rigid_velocity(M, lin, ang, act, flex, v, x):
    """The velocity of the actuators' motion alone (nx) into x: q̇_a from v (nv), ω0 = 0, ḟ = 0 (x_e = 0), v_lin
    from zero linear momentum; the state at which ``torque_split``'s linearising term is evaluated."""
    _zero_momentum_velocity(M, lin, ang, act, flex, np.zeros(ang.shape[0]), v, np.zeros(flex.shape[0]), x)


@njit(**JIT)
def torque_split(n_term, n_lin, tau_hat, ndo_on, tau, split):
    """The law's torques τ (wheels then arm, N m or N) split as Kraiem 2022 plots them (Fig. 3.15, 4.28), into
    ``split`` (3 × na): row 1 the linearising torque n_lin = n(x_e = 0) (``reduced_bias`` of r at ``rigid_velocity``,
    η = η̇ = 0: the nonlinear counterpart of D◇ q̇), row 2 the disturbance torque n − n_lin − τ̂_d (the estimated
    flexible and base states, D◇_x x̂_e, and the disturbance observer's estimate), row 0 the feedback torque, the
    rest: τ − n + τ̂_d (= M◇ v when no wheel saturates). n_term: n of the estimated state (``actuator_dynamics``)."""
    for i in range(n_term.shape[0]):
        d = tau_hat[i] if ndo_on else 0.0
        split[1, i] = n_lin[i]
        split[2, i] = n_term[i] - n_lin[i] - d
        split[0, i] = tau[i] - n_term[i] + d


@njit(**JIT)
def rotation_error(q_ref, q, out):
    """Rotation vector (rad, angle ≤ π, base frame) of q_ref⁻¹ ⊗ q (xyzw): ``attitude_math.attitude_error``, from
    the error quaternion of ``control.error_quaternion``."""
    e = np.empty(4)
    error_quaternion(q, q_ref, e)
    n = math.sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2])
    scale = 2.0 if n < 1e-12 else 2.0 * math.atan2(n, e[3]) / max(n, 1e-300)
    for a in range(3):
        out[a] = scale * e[a]


@njit(**JIT)
def least_norm(G, b):
    """pinv(G) b, G (3 × n) of full row rank (the wheels' effect on ω̇0): Gᵀ (G Gᵀ)⁻¹ b by the Cholesky factor of the
    3×3 G Gᵀ, the SVD's least-norm solution without one; ``np.linalg.pinv`` when G Gᵀ is singular or ill-conditioned
    (cond > 1e10, fewer than three wheels)."""
    n = G.shape[1]
    S = G @ G.T
    L = np.zeros((3, 3))
    if n >= 3:
        cholesky(S, 3, L)
        lo, hi = min(L[0, 0], L[1, 1], L[2, 2]), max(L[0, 0], L[1, 1], L[2, 2])
        if math.isfinite(L[0, 0] + L[1, 1] + L[2, 2]) and lo > 1e-5 * hi:  # cond(S) = cond(L)² < ~1e10
            y = np.empty(3)
            cholesky_solve(L, b, 3, y)
            return G.T @ y
    return np.linalg.pinv(G) @ b


@njit(**JIT)
def _unactuated(lin, ang, flex):
    """u = [base linear; base angular; flexible] (indices into x)."""
    u = np.empty(lin.shape[0] + ang.shape[0] + flex.shape[0], dtype=np.int64)
    u[:3] = lin
    u[3:6] = ang
    u[6:] = flex
    return u


@njit(**JIT)
def actuator_dynamics(M, r, lin, ang, act, flex):
    """The actuators' reduced dynamics M◇ q̈_a + n = τ_a (Kraiem 2022 (3.33)–(3.35)) from M (nx×nx) and
    r = bias − internal forces (nx): M◇ = M_aa − M_au M_uu⁻¹ M_ua, n = r_a − M_au M_uu⁻¹ r_u (u: base and
    flexible coordinates); also sol = M_uu⁻¹ [M_ua, r_u] ((nu)×(na + 1)), with which ``reduced_bias`` gives n of
    any other r at the same M without a second solve."""
    na = act.shape[0]
    u = _unactuated(lin, ang, flex)
    nu = u.shape[0]
    Mau = _sub(M, act, u)
    rhs = np.empty((nu, na + 1))
    rhs[:, :na] = _sub(M, u, act)
    for i in range(nu):
        rhs[i, na] = r[u[i]]
    sol = np.linalg.solve(_sub(M, u, u), rhs)
    M_dia = _sub(M, act, act) - Mau @ sol[:, :na]
    n_term = -(Mau @ sol[:, na])
    for i in range(na):
        n_term[i] += r[act[i]]
    return M_dia, n_term, sol


@njit(**JIT)
def reduced_bias(sol, r, lin, ang, act, flex):
    """n = r_a − M_au M_uu⁻¹ r_u (na) of r (nx) at the M that ``actuator_dynamics`` solved into sol: as M is
    symmetric, M_au M_uu⁻¹ = (M_uu⁻¹ M_ua)ᵀ = sol[:, :na]ᵀ, so no solve (O(nu·na))."""
    na = act.shape[0]
    u = _unactuated(lin, ang, flex)
    n_term = np.empty(na)
    for i in range(na):
        acc = r[act[i]]
        for k in range(u.shape[0]):
            acc -= sol[k, i] * r[u[k]]
        n_term[i] = acc
    return n_term


@njit(**JIT)
def ndo_estimate(qdot_a, flags, ndo_Phi, ndo_g, ndo_H, tau_hat):
    """The disturbance observer's estimate τ̂_d (N m or N, per actuator) at this control tick, in place:
    τ̂⁺ = Φ τ̂ + g + H q̇_a with the actuator rates q̇_a measured now and Φ, g, H left by the previous
    tick's ``ndo_refresh`` (nothing before the first refresh: τ̂ stays at its initial value)."""
    if flags[NDO_PENDING] == 0:
        return
    t_new = ndo_Phi @ tau_hat + ndo_g + ndo_H @ qdot_a
    tau_hat[:] = t_new
    flags[NDO_PENDING] = 0


@njit(**JIT)
def ndo_refresh(M_dia, n_term, qdot_a, tau_applied, Q_d, T, flags, ndo_Phi, ndo_g, ndo_H):
    """Kraiem 2022's nonlinear disturbance observer (4.12), τ̂̇_d = L_d (M◇ q̈_a + n − τ_a − τ̂_d) with
    L_d = Q_d M◇⁻¹ (4.33), over the control period T (s) that starts now, discretised with the measured
    rate change instead of the p-form (4.13)–(4.16) (which exists to avoid q̈ in continuous time): with
    M◇, n and τ_a held over the period and Φ = e^(−L_d T),

        τ̂⁺ = Φ τ̂ + (I − Φ) (n − τ_a + M◇ (q̇_a⁺ − q̇_a) / T),

    exact for a constant disturbance under a constant q̈ (the fixed point is τ_d, the error decays as Φᵏ).
    Stores Φ, g = (I − Φ)(n − τ_a − M◇ q̇_a / T) and H = (I − Φ) M◇ / T for the next tick's ``ndo_estimate``;
    M◇ and n of the tick's estimated state from ``actuator_dynamics`` (n without τ̂_d)."""
    na = n_term.shape[0]
    A = np.ascontiguousarray(-(Q_d @ np.linalg.inv(M_dia)) * T)
    Phi = _expm(A)
    I_Phi = np.eye(na) - Phi
    ndo_Phi[:, :] = Phi
    ndo_H[:, :] = I_Phi @ M_dia / T
    ndo_g[:] = I_Phi @ (n_term - tau_applied) - ndo_H @ qdot_a
    flags[NDO_PENDING] = 1


@njit(**JIT)
def ndi_command(M, M_dia, n_term, sol, ang, act, n_r, kp, kv, k_att, wheel_ff, wheel_limit, quat, omega, v, q_arm,
                ref_quat, ref_omega, ref_q, ref_qd, ref_qdd, flags, wheel_pinv, wheel_rate_ref, tau):
    """Actuator torques τ_a (wheels then arm; N m or N) of one control period into ``tau``, from M and the reduced
    dynamics M◇, n, sol of ``actuator_dynamics`` at the estimated state (n less the disturbance observer's τ̂_d when
    it runs, Kraiem 2022 (4.21)): τ = M◇ v + n (3.33)–(3.35) with the commands v
    (arm: q̈_d + kp ε + kv ε̇; wheels: the attitude hold q̇_rd = q̇_r − M_ωr⁺ M_ωω (ω_des − ω0),
    ω_des = R ω_ref − k_att θ, v_r = kv (q̇_rd − q̇_r) plus the feedforward that keeps ω̇0 = 0 when
    ``wheel_ff``). Wheel torques beyond ``wheel_limit`` are clipped first and the arm torques computed
    for the wheel accelerations the clipped torques produce. Sets flags[SATURATED] and
    ``wheel_rate_ref`` (q̇_rd, rad/s); ``wheel_pinv`` (n_r×3) is made on the first call (M_ωr is constant)."""
    na = act.shape[0]
    n_m = na - n_r
    v_cmd = np.zeros(na)
    for i in range(n_m):
        j = n_r + i
        v_cmd[j] = ref_qdd[i] + kp[j] * (ref_q[i] - q_arm[i]) + kv[j] * (ref_qd[i] - v[act[j]])
    if n_r:
        theta = np.empty(3)
        rotation_error(ref_quat, quat, theta)
        rel = np.empty(4)
        error_quaternion(ref_quat, quat, rel)  # quat⁻¹ ⊗ ref_quat
        R_rb = np.empty((3, 3))  # base ← reference
        quat_to_matrix(rel[0], rel[1], rel[2], rel[3], R_rb)
        dw = R_rb @ ref_omega - k_att * theta
        for a in range(3):
            dw[a] -= omega[a]
        if flags[PINV_VALID] == 0:  # wheels ride on the base: M_ωr = [I_s a_i] is constant
            wheel_pinv[:, :] = np.linalg.pinv(_sub(M, ang, act[:n_r]))
            flags[PINV_VALID] = 1
        dq_r = -(wheel_pinv @ (_sub(M, ang, ang) @ dw))
        for i in range(n_r):
            v_cmd[i] = kv[i] * dq_r[i]
        if wheel_ff:  # Kraiem 2022 (3.66) derivative: ẍ_u = −M_uu⁻¹ (M_ua q̈_a + r_u), ω̇0 = 0, least norm
            G = sol[3:6, :n_r].copy()
            rest = sol[3:6, n_r:na] @ v_cmd[n_r:] + sol[3:6, na]
            ff = least_norm(G, rest)
            for i in range(n_r):
                v_cmd[i] -= ff[i]
        for i in range(n_r):
            wheel_rate_ref[i] = v[act[i]] + dq_r[i]
    out = M_dia @ v_cmd + n_term
    sat = False
    for i in range(n_r):
        if abs(out[i]) > wheel_limit[i]:
            sat = True
    flags[SATURATED] = 1 if sat else 0
    if sat:
        tau_r = np.empty(n_r)
        for i in range(n_r):
            tau_r[i] = min(max(out[i], -wheel_limit[i]), wheel_limit[i])
        Mrr, Mrm = M_dia[:n_r, :n_r].copy(), M_dia[:n_r, n_r:].copy()
        Mmr, Mmm = M_dia[n_r:, :n_r].copy(), M_dia[n_r:, n_r:].copy()
        vm = v_cmd[n_r:].copy()
        qdd_r = np.linalg.solve(Mrr, tau_r - Mrm @ vm - n_term[:n_r])
        out_m = Mmr @ qdd_r + Mmm @ vm + n_term[n_r:]
        for i in range(n_r):
            out[i] = tau_r[i]
        for i in range(n_m):
            out[n_r + i] = out_m[i]
    for i in range(na):
        tau[i] = out[i]


@njit(**JIT)
def ndi_observe(M, q_act, y, tau_applied, lin, ang, act, flex, K_f, C_f, L, T, refresh, flags, disc_q, Phi, Gamma, B_tau,
                x_hat):
    """x̂⁺ = Φ x̂ + Γ (B_τ τ + L y) over one control period T (s) with the torques actually applied; the
    discretisation of A_L = A_e − L C_e is rebuilt from M when flags[DISC_VALID] is 0 or the arm
    configuration q_act moved by more than ``refresh`` (rad or m) since the last rebuild."""
    moved = 0.0
    for i in range(q_act.shape[0]):
        moved = max(moved, abs(q_act[i] - disc_q[i]))
    if flags[DISC_VALID] == 0 or moved > refresh:
        n_e, n_q, n_f = x_hat.shape[0], act.shape[0], flex.shape[0]
        A_e = np.empty((n_e, n_e))
        reduced_at_rest(M, lin, ang, act, flex, K_f, C_f, A_e, B_tau, np.empty((n_q, n_q)), np.empty((n_q, n_e)),
                        np.empty((n_q, n_e)))
        A_L = A_e.copy()
        for i in range(n_e):  # − L C_e: C_e selects ω0, columns n_f .. n_f + 3
            for a in range(3):
                A_L[i, n_f + a] -= L[i, a]
        observer_discretisation(A_L, T, Phi, Gamma)
        disc_q[:] = q_act
        flags[DISC_VALID] = 1
    x_new = Phi @ x_hat + Gamma @ (B_tau @ tau_applied + L @ y)
    x_hat[:] = x_new


@njit(**JIT)
def augmented_mass(parent, kind, axis, inertia, armature, idx_v, R_rel, p_rel, modal_B, M):
    """M = [[H, Bᵀ on the base rows], [B on the base columns, I]] (nx×nx) at the joint transforms (R_rel,
    p_rel), appendages on the base (B = ``SystemModel.base_modal_coupling``, n_η×6)."""
    nv = armature.shape[0]
    ne = modal_B.shape[0]
    H = np.empty((nv, nv))
    mass_matrix(parent, kind, axis, inertia, armature, idx_v, R_rel, p_rel, H)
    M[:, :] = 0.0
    M[:nv, :nv] = H
    for k in range(ne):
        M[nv + k, nv + k] = 1.0
        for a in range(6):
            M[nv + k, a] = modal_B[k, a]
            M[a, nv + k] = modal_B[k, a]


@njit(**JIT)
def augmented_bias(parent, kind, axis, inertia, idx_v, R_rel, p_rel, modal_B, neg_omega2, neg_2zo, v, eta, etadot, r):
    """r = bias − internal forces (nx) at the joint transforms (R_rel, p_rel) and the state (v, η, η̇),
    appendages on the base: RNEA's bias, plus v_b ×* (Bᵀ η̇) on the base rows; modal rows Ω² η + 2ζΩ η̇
    (``neg_omega2`` = −Ω², ``neg_2zo`` = −2ζΩ). No spring joints."""
    nv = v.shape[0]
    ne = eta.shape[0]
    bias_forces(parent, kind, axis, inertia, idx_v, R_rel, p_rel, v, r[:nv])
    P = np.zeros(6)  # modal momentum as a base-frame wrench [f; n]
    for k in range(ne):
        for a in range(6):
            P[a] += modal_B[k, a] * etadot[k]
    fx, fy, fz, nx, ny, nz = P[0], P[1], P[2], P[3], P[4], P[5]
    vx, vy, vz, wx, wy, wz = v[0], v[1], v[2], v[3], v[4], v[5]
    r[0] += wy * fz - wz * fy  # v_b ×* P = [ω × f; v × f + ω × n]
    r[1] += wz * fx - wx * fz
    r[2] += wx * fy - wy * fx
    r[3] += vy * fz - vz * fy + wy * nz - wz * ny
    r[4] += vz * fx - vx * fz + wz * nx - wx * nz
    r[5] += vx * fy - vy * fx + wx * ny - wy * nx
    for k in range(ne):
        r[nv + k] = -(neg_omega2[k] * eta[k] + neg_2zo[k] * etadot[k])
