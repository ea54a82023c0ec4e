"""Compiled (numba) attitude laws: THE implementation of quaternion_pd, smc (Caldera 2019),
twisting_smc and backstepping (Ruggiero 2020). The Python loop's classes in
``sms_cli.sim.laws.attitude`` call these kernels with the body quantities of their body model
(Pinocchio's for ``SystemBody``); the compiled loop calls them through ``attitude_law``.

Every law kernel has the same arguments:

    law(qe, omega, omega_r, domega_r, J, Jd, h, par, mem, t, out)

qe: error quaternion q_R⁻¹ ⊗ q_B (xyzw, w ≥ 0; ``control.error_quaternion``); omega: ω (base frame,
rad/s); omega_r, domega_r: the reference's rate and its base-frame derivative in the base frame
(``TrackingError.omega_r``/``domega_r``); J, Jd: inertia and its rate (3×3, kg m²); h: internal
momentum (N m s, base frame); par: the law's parameters (layouts below; a gain is a 3×3 matrix,
row-major: scalar and per-axis gains are diagonal); mem: the law's state between calls; t: time
(s); out: the torque on the base (N m, base frame). Conventions as in ``sms_cli.sim.laws.attitude``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from sms_cli.sim.compiled import HOT, JIT
from sms_cli.sim.compiled.control import mrp_feedback

# law codes of ``attitude_law`` (the compiled loop's dispatch)
MRP_FEEDBACK, QUATERNION_PD, SMC, TWISTING_SMC, BACKSTEPPING = 0, 1, 2, 3, 4

# parameter layouts (offsets into ``par``); G = 9 numbers of a 3×3 gain, row-major
PD_KP, PD_KD, PD_KI, PD_LIMIT, PD_FEEDFORWARD, PD_N = 0, 9, 18, 27, 28, 29
PD_MEM = 5  # [clock started, previous t, ∫θ_e dt (3)]
SMC_K, SMC_C, SMC_MU, SMC_SIGN, SMC_MOMENTUM, SMC_N = 0, 9, 18, 27, 28, 29
TW_K1, TW_K2, TW_LAM, TW_ETA, TW_SIGN, TW_FILTER, TW_N = 0, 9, 18, 27, 36, 37, 38
TW_MEM = 8  # [clock started, previous t, previous σ (3), σ̇ (3)]
BS_K1, BS_K2, BS_GYRO, BS_N = 0, 9, 18, 19
MRP_N = 8  # [K, P, Ki, integral_limit, control_law_type, L (3)]


@njit(**HOT)
def _gain(par, at, x0, x1, x2, i):
    """Row i of the 3×3 gain at par[at:at+9] times x."""
    return par[at + 3 * i] * x0 + par[at + 3 * i + 1] * x1 + par[at + 3 * i + 2] * x2


@njit(**HOT)
def _sign(x):
    """np.sign: ±1, and 0 (or NaN) for 0 (or NaN)."""
    if x > 0:
        return 1.0
    if x < 0:
        return -1.0
    return x


@njit(**HOT)
def _clock(mem, t):
    """Time since the previous call (mem[0]: started flag, mem[1]: previous t); 0 on the first call."""
    dt = t - mem[1] if mem[0] != 0.0 else 0.0
    mem[0] = 1.0
    mem[1] = t
    return dt


@njit(**JIT)
def sliding_surface(qe, omega, omega_r, par, at, out):
    """σ = δω + Λ q_v (δω = ω − ω_r; Λ the 3×3 gain at par[at:at+9]): the smc and twisting surfaces."""
    for i in range(3):
        out[i] = (omega[i] - omega_r[i]) + _gain(par, at, qe[0], qe[1], qe[2], i)


@njit(**HOT)
def _surface(qe, omega, omega_r, par, at, i):
    return (omega[i] - omega_r[i]) + _gain(par, at, qe[0], qe[1], qe[2], i)


@njit(**HOT)
def _qv_dot(qe, omega, omega_r, out):
    """q̇_v = ½ (q_w δω + q_v × δω)."""
    d0, d1, d2 = omega[0] - omega_r[0], omega[1] - omega_r[1], omega[2] - omega_r[2]
    x, y, z, w = qe[0], qe[1], qe[2], qe[3]
    out[0] = 0.5 * (w * d0 + (y * d2 - z * d1))
    out[1] = 0.5 * (w * d1 + (z * d0 - x * d2))
    out[2] = 0.5 * (w * d2 + (x * d1 - y * d0))


@njit(**HOT)
def _gyroscopic(omega, J, h, out):
    """ω × (J ω + h)."""
    w0, w1, w2 = omega[0], omega[1], omega[2]
    H0 = (J[0, 0] * w0 + J[0, 1] * w1 + J[0, 2] * w2) + h[0]
    H1 = (J[1, 0] * w0 + J[1, 1] * w1 + J[1, 2] * w2) + h[1]
    H2 = (J[2, 0] * w0 + J[2, 1] * w1 + J[2, 2] * w2) + h[2]
    out[0] = w1 * H2 - w2 * H1
    out[1] = w2 * H0 - w0 * H2
    out[2] = w0 * H1 - w1 * H0


@njit(**JIT)
def quaternion_pd(qe, omega, omega_r, domega_r, J, Jd, h, par, mem, t, out):
    """τ = −k_p θ_e − k_d δω − k_i ∫θ_e dt [+ ω × (J ω + h) + J (ω̇_r − ω × ω_r)], θ_e = 2 q_v.

    par: [k_p (9), k_d (9), k_i (9), integral_limit, feedforward (0/1)]; mem (5): [clock started,
    previous t, ∫θ_e dt (3)], the integral advanced by θ_e × (t − previous t) (0 on the first call)
    and each component clipped to ±integral_limit, only when some k_i ≠ 0. Jd is not used."""
    th0, th1, th2 = 2.0 * qe[0], 2.0 * qe[1], 2.0 * qe[2]
    d0, d1, d2 = omega[0] - omega_r[0], omega[1] - omega_r[1], omega[2] - omega_r[2]
    dt = _clock(mem, t)
    for i in range(3):
        out[i] = -_gain(par, PD_KP, th0, th1, th2, i) - _gain(par, PD_KD, d0, d1, d2, i)
    integral = False
    for j in range(9):
        if par[PD_KI + j] != 0.0:
            integral = True
    if integral:
        lim = par[PD_LIMIT]
        for i, th in ((0, th0), (1, th1), (2, th2)):
            mem[2 + i] = min(max(mem[2 + i] + th * dt, -lim), lim)
        for i in range(3):
            out[i] -= _gain(par, PD_KI, mem[2], mem[3], mem[4], i)
    if par[PD_FEEDFORWARD] != 0.0:
        g = np.empty(3)
        _gyroscopic(omega, J, h, g)
        w0, w1, w2 = omega[0], omega[1], omega[2]
        r0, r1, r2 = omega_r[0], omega_r[1], omega_r[2]
        a0 = domega_r[0] - (w1 * r2 - w2 * r1)
        a1 = domega_r[1] - (w2 * r0 - w0 * r2)
        a2 = domega_r[2] - (w0 * r1 - w1 * r0)
        for i in range(3):
            out[i] += g[i] + (J[i, 0] * a0 + J[i, 1] * a1 + J[i, 2] * a2)


@njit(**JIT)
def smc(qe, omega, omega_r, domega_r, J, Jd, h, par, mem, t, out):
    """Caldera 2019 first-order SMC with self-consistent signs, s = δω + k q_v:

        τ = ω × (J ω + h) + J (ω̇_r − ω × ω_r − k q̇_v − c tanh(μ s))     (or sign(s))

    par: [k (9), c (9), μ (9), sign (0: tanh, 1: sign), momentum (0: h left out)]. Jd, mem, t are
    not used."""
    s0 = _surface(qe, omega, omega_r, par, SMC_K, 0)
    s1 = _surface(qe, omega, omega_r, par, SMC_K, 1)
    s2 = _surface(qe, omega, omega_r, par, SMC_K, 2)
    if par[SMC_SIGN] != 0.0:
        f0, f1, f2 = _sign(s0), _sign(s1), _sign(s2)
    else:
        f0 = math.tanh(_gain(par, SMC_MU, s0, s1, s2, 0))
        f1 = math.tanh(_gain(par, SMC_MU, s0, s1, s2, 1))
        f2 = math.tanh(_gain(par, SMC_MU, s0, s1, s2, 2))
    qd = np.empty(3)
    _qv_dot(qe, omega, omega_r, qd)
    g = np.empty(3)
    if par[SMC_MOMENTUM] != 0.0:
        _gyroscopic(omega, J, h, g)
    else:
        _gyroscopic(omega, J, np.zeros(3), g)
    w0, w1, w2 = omega[0], omega[1], omega[2]
    r0, r1, r2 = omega_r[0], omega_r[1], omega_r[2]
    a = np.empty(3)
    a[0] = domega_r[0] - (w1 * r2 - w2 * r1)
    a[1] = domega_r[1] - (w2 * r0 - w0 * r2)
    a[2] = domega_r[2] - (w0 * r1 - w1 * r0)
    for i in range(3):
        a[i] = a[i] - _gain(par, SMC_K, qd[0], qd[1], qd[2], i) - _gain(par, SMC_C, f0, f1, f2, i)
    for i in range(3):
        out[i] = g[i] + (J[i, 0] * a[0] + J[i, 1] * a[1] + J[i, 2] * a[2])


@njit(**JIT)
def twisting_smc(qe, omega, omega_r, domega_r, J, Jd, h, par, mem, t, out):
    """Ruggiero 2020 twisting SMC, σ = λ q_v + δω:

        u = −k₁ tanh(η σ) − k₂ tanh(η σ̇)     (or sign)

    σ̇: backward difference (σ − σ_prev) / (t − t_prev) between calls (0 until the second call, kept
    when t − t_prev ≤ 0) through a first-order filter of time constant T_f: σ̇ += a (raw − σ̇),
    a = dt / (T_f + dt). par: [k₁ (9), k₂ (9), λ (9), η (9), sign (0: tanh, 1: sign), T_f (s)];
    mem (8): [clock started, previous t, previous σ (3), σ̇ (3)]. J, Jd, h are not used."""
    started = mem[0] != 0.0
    dt = _clock(mem, t)
    sig = np.empty(3)
    for i in range(3):
        sig[i] = _surface(qe, omega, omega_r, par, TW_LAM, i)
    if started and dt > 0:
        a = dt / (par[TW_FILTER] + dt)
        for i in range(3):
            raw = (sig[i] - mem[2 + i]) / dt
            mem[5 + i] = mem[5 + i] + a * (raw - mem[5 + i])
    for i in range(3):
        mem[2 + i] = sig[i]
    sd0, sd1, sd2 = mem[5], mem[6], mem[7]
    if par[TW_SIGN] != 0.0:
        f0, f1, f2 = _sign(sig[0]), _sign(sig[1]), _sign(sig[2])
        g0, g1, g2 = _sign(sd0), _sign(sd1), _sign(sd2)
    else:
        f0 = math.tanh(_gain(par, TW_ETA, sig[0], sig[1], sig[2], 0))
        f1 = math.tanh(_gain(par, TW_ETA, sig[0], sig[1], sig[2], 1))
        f2 = math.tanh(_gain(par, TW_ETA, sig[0], sig[1], sig[2], 2))
        g0 = math.tanh(_gain(par, TW_ETA, sd0, sd1, sd2, 0))
        g1 = math.tanh(_gain(par, TW_ETA, sd0, sd1, sd2, 1))
        g2 = math.tanh(_gain(par, TW_ETA, sd0, sd1, sd2, 2))
    for i in range(3):
        out[i] = -_gain(par, TW_K1, f0, f1, f2, i) - _gain(par, TW_K2, g0, g1, g2, i)


@njit(**HOT)
def _backstepping_rates(qe, omega, omega_r, par, wc, wt):
    """ω_c = −K₁ q_v + ω_r and ω̃ = ω − ω_c."""
    for i in range(3):
        wc[i] = -_gain(par, BS_K1, qe[0], qe[1], qe[2], i) + omega_r[i]
        wt[i] = omega[i] - wc[i]


@njit(**JIT)
def backstepping(qe, omega, omega_r, domega_r, J, Jd, h, par, mem, t, out):
    """Ruggiero 2020 backstepping, ω_c = −K₁ q_v + ω_r, ω̃ = ω − ω_c:

        γ = (J ω_c) × ω_c − J ω̇_c − J̇ ω_c,   ω̇_c = −K₁ q̇_v + ω̇_r − ω × ω_r,
        u = −K₂ ω̃ − q_v − T̂_dis − γ + ω_c × (J ω̃) + ½ J̇ ω̃,

    T̂_dis = −ω × h (gyroscopic) or 0. par: [K₁ (9), K₂ (9), gyroscopic (0/1)]. mem, t are not used."""
    wc, wt = np.empty(3), np.empty(3)
    _backstepping_rates(qe, omega, omega_r, par, wc, wt)
    qd = np.empty(3)
    _qv_dot(qe, omega, omega_r, qd)
    w0, w1, w2 = omega[0], omega[1], omega[2]
    r0, r1, r2 = omega_r[0], omega_r[1], omega_r[2]
    wr_x = (w1 * r2 - w2 * r1, w2 * r0 - w0 * r2, w0 * r1 - w1 * r0)
    wcd = np.empty(3)
    for i in range(3):
        wcd[i] = -_gain(par, BS_K1, qd[0], qd[1], qd[2], i) + domega_r[i] - wr_x[i]
    Jwc = np.empty(3)
    Jwt = np.empty(3)
    for i in range(3):
        Jwc[i] = J[i, 0] * wc[0] + J[i, 1] * wc[1] + J[i, 2] * wc[2]
        Jwt[i] = J[i, 0] * wt[0] + J[i, 1] * wt[1] + J[i, 2] * wt[2]
    gamma = np.empty(3)
    gamma[0] = Jwc[1] * wc[2] - Jwc[2] * wc[1]
    gamma[1] = Jwc[2] * wc[0] - Jwc[0] * wc[2]
    gamma[2] = Jwc[0] * wc[1] - Jwc[1] * wc[0]
    for i in range(3):
        gamma[i] = (gamma[i] - (J[i, 0] * wcd[0] + J[i, 1] * wcd[1] + J[i, 2] * wcd[2])
                    - (Jd[i, 0] * wc[0] + Jd[i, 1] * wc[1] + Jd[i, 2] * wc[2]))
    Td = np.zeros(3)
    if par[BS_GYRO] != 0.0:
        Td[0] = -(w1 * h[2] - w2 * h[1])
        Td[1] = -(w2 * h[0] - w0 * h[2])
        Td[2] = -(w0 * h[1] - w1 * h[0])
    c = (wc[1] * Jwt[2] - wc[2] * Jwt[1], wc[2] * Jwt[0] - wc[0] * Jwt[2], wc[0] * Jwt[1] - wc[1] * Jwt[0])
    for i in range(3):
        out[i] = (-_gain(par, BS_K2, wt[0], wt[1], wt[2], i) - qe[i] - Td[i] - gamma[i] + c[i]
                  + 0.5 * (Jd[i, 0] * wt[0] + Jd[i, 1] * wt[1] + Jd[i, 2] * wt[2]))


@njit(**JIT)
def backstepping_lyapunov(qe, omega, omega_r, J, par):
    """V₂ = q_vᵀq_v + (1 − q_w)² + ½ ω̃ᵀ J ω̃ of the backstepping law (par as ``backstepping``)."""
    wc, wt = np.empty(3), np.empty(3)
    _backstepping_rates(qe, omega, omega_r, par, wc, wt)
    quad = 0.0
    for i in range(3):
        quad += wt[i] * (J[i, 0] * wt[0] + J[i, 1] * wt[1] + J[i, 2] * wt[2])
    return qe[0] * qe[0] + qe[1] * qe[1] + qe[2] * qe[2] + (1.0 - qe[3]) ** 2 + 0.5 * quad


# ----------------------------------------------------------------------------- body quantities
@njit(**JIT)
def wheel_momentum(G, Js, omega, wheel_speed, out):
    """h = Σ ĝ_i J_s,i (ĝ_iᵀ ω + Ω_i) (N m s, base frame): a rigid body's wheels (G: axes as columns)."""
    out[0] = out[1] = out[2] = 0.0
    for i in range(Js.shape[0]):
        g0, g1, g2 = G[0, i], G[1, i], G[2, i]
        hs = Js[i] * ((g0 * omega[0] + g1 * omega[1] + g2 * omega[2]) + wheel_speed[i])
        out[0] += g0 * hs
        out[1] += g1 * hs
        out[2] += g2 * hs


@njit(**JIT)
def system_momentum(quat, k_com, J, omega, out):
    """h = Rᵀ k_G − J ω (N m s, base frame): the system's angular momentum about its CoM (world
    frame, k_G) less the locked body's, R = R(quat) base → world (``SystemBody.internal_momentum``)."""
    x, y, z, w = quat[0], quat[1], quat[2], quat[3]
    R = ((1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)),
         (2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)),
         (2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)))
    for i in range(3):
        out[i] = ((R[0][i] * k_com[0] + R[1][i] * k_com[1] + R[2][i] * k_com[2])
                  - (J[i, 0] * omega[0] + J[i, 1] * omega[1] + J[i, 2] * omega[2]))


# ----------------------------------------------------------------------------- the compiled loop's dispatch
@njit(**JIT)
def attitude_law(code, qe, omega, omega_r, domega_r, wheel_speed, J, Jd, h, G, Js, par, mem, t, out):
    """The law ``code`` (MRP_FEEDBACK, QUATERNION_PD, SMC, TWISTING_SMC, BACKSTEPPING) into ``out``.
    mrp_feedback takes its wheel momentum from G, Js and the wheel speeds itself (Basilisk's
    formula) and par = [K, P, Ki, integral_limit, control_law_type, L (3)]; the others take h."""
    if code == MRP_FEEDBACK:
        L = np.empty(3)
        L[0], L[1], L[2] = par[5], par[6], par[7]
        mrp_feedback(qe, omega, omega_r, domega_r, wheel_speed, J, G, Js, par[0], par[1], par[2], par[3], int(par[4]),
                     L, mem, t, out)
    elif code == QUATERNION_PD:
        quaternion_pd(qe, omega, omega_r, domega_r, J, Jd, h, par, mem, t, out)
    elif code == SMC:
        smc(qe, omega, omega_r, domega_r, J, Jd, h, par, mem, t, out)
    elif code == TWISTING_SMC:
        twisting_smc(qe, omega, omega_r, domega_r, J, Jd, h, par, mem, t, out)
    else:
        backstepping(qe, omega, omega_r, domega_r, J, Jd, h, par, mem, t, out)
