"""Compiled (numba) control pieces: the attitude tracking error, Basilisk's ``mrpFeedback`` law
and the reaction-wheel actuator model. ``mrp_feedback`` is THE implementation of that law: the
Python engine's ``sms_cli.sim.laws.attitude.MrpFeedback`` calls it too.

Frames and units as in ``sms_cli.sim.laws.attitude`` (quaternions xyzw, base → world; rates in
the base frame, rad/s; torques N m) and ``sms_cli.sim.actuators`` (a wheel motor torque τ_w
puts −τ_w a on the base).
"""

from __future__ import annotations

import math

from numba import njit

from sms_cli.sim.compiled import JIT as _JIT


@njit(**_JIT)
def error_quaternion(qb, qr, out):
    """q_e = q_R⁻¹ ⊗ q_B (base relative to the reference), normalised, sign with w ≥ 0."""
    bx, by, bz, bw = qb[0], qb[1], qb[2], qb[3]
    rx, ry, rz, rw = qr[0], qr[1], qr[2], qr[3]
    nr = math.sqrt(bx * bx + by * by + bz * bz + bw * bw) * math.sqrt(rx * rx + ry * ry + rz * rz + rw * rw)
    x = (rw * bx - rx * bw - ry * bz + rz * by) / nr
    y = (rw * by + rx * bz - ry * bw - rz * bx) / nr
    z = (rw * bz - rx * by + ry * bx - rz * bw) / nr
    w = (rw * bw + rx * bx + ry * by + rz * bz) / nr
    if w < 0:
        x, y, z, w = -x, -y, -z, -w
    out[0], out[1], out[2], out[3] = x, y, z, w


@njit(**_JIT)
def error_angle(qb, qr):
    """Eigen-axis angle (rad, ≤ π) of q_R⁻¹ ⊗ q_B: |attitude_error(q_R, q_B)|."""
    bx, by, bz, bw = qb[0], qb[1], qb[2], qb[3]
    rx, ry, rz, rw = qr[0], qr[1], qr[2], qr[3]
    x = rw * bx - rx * bw - ry * bz + rz * by
    y = rw * by + rx * bz - ry * bw - rz * bx
    z = rw * bz - rx * by + ry * bx - rz * bw
    w = rw * bw + rx * bx + ry * by + rz * bz
    return 2.0 * math.atan2(math.sqrt(x * x + y * y + z * z), abs(w))


@njit(**_JIT)
def mrp_feedback(qe, omega, omega_r, domega_r, wheel_speed, I, G, Js, K, P, Ki, integral_limit, law_type, L, mem, t,
                 out):
    """Basilisk's mrpFeedback torque on the spacecraft (N m, base frame) into ``out``:

        L_r = −K σ − P δω − P K_i z + v × (I ω + G_s h_s) − I (ω × ω_r − ω̇_r) − L

    σ = MRP of q_e; δω = ω − ω_r; h_s,i = J_s,i (ĝ_iᵀ ω + Ω_i); v = ω_r + K_i z (law_type 0) or ω (1);
    z = K ∫σ dt + I δω when K_i > 0 (each K∫σ component clipped to integral_limit). ``mem`` holds
    [prior_time, K∫σ (3)]; the step is t − prior_time, zero when prior_time is 0 (Basilisk's sentinel).
    ``G`` (3 × n) and ``Js`` (n) may be empty (no wheel momentum compensation).
    """
    d = 1.0 + qe[3]
    s0, s1, s2 = qe[0] / d, qe[1] / d, qe[2] / d
    w0, w1, w2 = omega[0], omega[1], omega[2]
    r0, r1, r2 = omega_r[0], omega_r[1], omega_r[2]
    a0, a1, a2 = domega_r[0], domega_r[1], domega_r[2]
    dw0, dw1, dw2 = w0 - r0, w1 - r1, w2 - r2
    dt = 0.0 if mem[0] == 0.0 else t - mem[0]
    mem[0] = t
    z0 = z1 = z2 = 0.0
    if Ki > 0:
        for i, sg in ((0, s0), (1, s1), (2, s2)):
            v = mem[1 + i] + K * dt * sg
            mem[1 + i] = v if abs(v) <= integral_limit else math.copysign(integral_limit, v)
        z0 = mem[1] + I[0, 0] * dw0 + I[0, 1] * dw1 + I[0, 2] * dw2
        z1 = mem[2] + I[1, 0] * dw0 + I[1, 1] * dw1 + I[1, 2] * dw2
        z2 = mem[3] + I[2, 0] * dw0 + I[2, 1] * dw1 + I[2, 2] * dw2
    PKi = P * Ki
    L0 = K * s0 + P * dw0 + PKi * z0
    L1 = K * s1 + P * dw1 + PKi * z1
    L2 = K * s2 + P * dw2 + PKi * z2
    H0 = I[0, 0] * w0 + I[0, 1] * w1 + I[0, 2] * w2
    H1 = I[1, 0] * w0 + I[1, 1] * w1 + I[1, 2] * w2
    H2 = I[2, 0] * w0 + I[2, 1] * w1 + I[2, 2] * w2
    for i in range(Js.shape[0]):
        g0, g1, g2 = G[0, i], G[1, i], G[2, i]
        hs = Js[i] * (g0 * w0 + g1 * w1 + g2 * w2 + wheel_speed[i])
        H0 += hs * g0
        H1 += hs * g1
        H2 += hs * g2
    if law_type == 0:
        v0, v1, v2 = r0 + Ki * z0, r1 + Ki * z1, r2 + Ki * z2
    else:
        v0, v1, v2 = w0, w1, w2
    L0 -= v1 * H2 - v2 * H1
    L1 -= v2 * H0 - v0 * H2
    L2 -= v0 * H1 - v1 * H0
    c0, c1, c2 = w1 * r2 - w2 * r1 - a0, w2 * r0 - w0 * r2 - a1, w0 * r1 - w1 * r0 - a2
    L0 += I[0, 0] * c0 + I[0, 1] * c1 + I[0, 2] * c2 + L[0]
    L1 += I[1, 0] * c0 + I[1, 1] * c1 + I[1, 2] * c2 + L[1]
    L2 += I[2, 0] * c0 + I[2, 1] * c1 + I[2, 2] * c2 + L[2]
    out[0], out[1], out[2] = -L0, -L1, -L2


@njit(**_JIT)
def clip_attitude_torque(T, limit):
    """The thrusters' ideal torque limit: each component of T clipped to ±limit in place (inf: none).
    Returns whether any component was clipped (``Simulation._control``, attitude_torque_limit)."""
    sat = False
    for a in range(3):
        if abs(T[a]) > limit * (1 + 1e-12):
            sat = True
        T[a] = min(max(T[a], -limit), limit)
    return sat


# ----------------------------------------------------------------------------- wheels
@njit(**_JIT)
def allocate_and_clip(T, wheel_speed, A_pinv, null, spin, null_gain, target_speed, max_torque, tau_out):
    """Wheel motor torques for the base torque T: −A⁺T (− null-space momentum management), then
    the motor torque limit. Returns whether any wheel saturated (``WheelArray.allocate`` +
    ``clip_torque``)."""
    n = tau_out.shape[0]
    sat = False
    for i in range(n):
        acc = -(A_pinv[i, 0] * T[0] + A_pinv[i, 1] * T[1] + A_pinv[i, 2] * T[2])
        if null_gain > 0 and n > 3:
            for j in range(n):
                acc -= null_gain * null[i, j] * spin[j] * (wheel_speed[j] - target_speed)
        lim = max_torque[i]
        if abs(acc) > lim * (1 + 1e-12):
            sat = True
        tau_out[i] = min(max(acc, -lim), lim)
    return sat


@njit(**_JIT)
def may_reach_limit(speed, tau, eff_inertia, max_speed, horizon):
    """Whether a wheel could reach its speed limit within ``horizon`` s (factor 2 margin)."""
    for i in range(speed.shape[0]):
        if abs(speed[i]) + 2.0 * abs(tau[i]) / eff_inertia[i] * horizon >= max_speed[i]:
            return True
    return False


@njit(**_JIT)
def limited_torque(tau, speed, eff_inertia, max_speed, dt, coulomb, viscous, out):
    """Torque that cannot push a wheel past its speed limit within dt, plus friction
    (``WheelArray.speed_limited`` + ``friction_torque``)."""
    for i in range(tau.shape[0]):
        x = tau[i]
        if x != 0.0 and (x > 0) == (speed[i] > 0) and speed[i] != 0.0:
            cap = eff_inertia[i] * max(max_speed[i] - abs(speed[i]), 0.0) / dt
            if abs(x) > cap:
                x = math.copysign(cap, x)
        sgn = 0.0 if speed[i] == 0.0 else math.copysign(1.0, speed[i])
        out[i] = x - coulomb * sgn - viscous * speed[i]
