"""Compiled (numba) attitude references: THE implementation of a phase's attitude profile (step, or the
quintic rest-to-rest eigen-axis slew) and of the reference rates the laws see in the base frame. The
Python loop's ``sms_cli.sim.references.AttitudeProfile.at`` and ``laws.attitude.TrackingError`` call
these kernels; the compiled loop calls them every tick.

A profile is the array ``prof`` (PROF_N): [q_start (4), rotation vector r (3, rad, start frame), T (s; 0:
step), q_target (4)], quaternions xyzw (world ← reference). Smooth: q(τ) = q_start ⊗ exp(p(τ/T) r),
ω_ref = ṗ/T r, ω̇_ref = p̈/T² r (reference frame), p the quintic blend.
"""

from __future__ import annotations

import math

from numba import njit

from sms_cli.sim.compiled import JIT
from sms_cli.sim.compiled.arm_laws import quintic

PROF_Q0, PROF_ROT, PROF_T, PROF_QT, PROF_N = 0, 4, 7, 8, 12


@njit(**JIT)
def quat_mul_exp(ax, ay, az, aw, r0, r1, r2, out):
    """out = a ⊗ exp(r) (xyzw, Hamilton product; r a rotation vector in rad, in the frame of a): THE
    quaternion exponential of the project, exp(r) = [sin(|r|/2) r/|r|, cos(|r|/2)], [r/2, 1] to first order
    below |r| = 1e-12; not renormalised. The attitude profiles and the sensors' attitude error use it."""
    angle = math.sqrt(r0 * r0 + r1 * r1 + r2 * r2)
    if angle < 1e-12:
        bx, by, bz, bw = 0.5 * r0, 0.5 * r1, 0.5 * r2, 1.0
    else:
        s = math.sin(0.5 * angle) / angle
        bx, by, bz, bw = s * r0, s * r1, s * r2, math.cos(0.5 * angle)
    out[0] = aw * bx + ax * bw + ay * bz - az * by
    out[1] = aw * by - ax * bz + ay * bw + az * bx
    out[2] = aw * bz + ax * by - ay * bx + az * bw
    out[3] = aw * bw - ax * bx - ay * by - az * bz


@njit(**JIT)
def attitude_reference(prof, tau, q, w, wd):
    """The reference at τ s from the phase start: quaternion q (xyzw), ω_ref and ω̇_ref (rad/s, rad/s²,
    reference frame) into q, w, wd."""
    T = prof[PROF_T]
    if T <= 0.0:
        for a in range(4):
            q[a] = prof[PROF_QT + a]
        for a in range(3):
            w[a] = 0.0
            wd[a] = 0.0
        return
    p, dp, ddp = quintic(tau / T)
    quat_mul_exp(prof[PROF_Q0], prof[PROF_Q0 + 1], prof[PROF_Q0 + 2], prof[PROF_Q0 + 3],
                 p * prof[PROF_ROT], p * prof[PROF_ROT + 1], p * prof[PROF_ROT + 2], q)
    for a in range(3):
        w[a] = dp / T * prof[PROF_ROT + a]
        wd[a] = ddp / (T * T) * prof[PROF_ROT + a]


@njit(**JIT)
def reference_rates(qe, w_ref, wd_ref, omega_r, domega_r):
    """ω_r = Cᵀ ω_ref and Cᵀ ω̇_ref (base frame) into omega_r, domega_r, C = R(q_e) base → reference
    (q_e = q_R⁻¹ ⊗ q_B, ``control.error_quaternion``); the laws add − ω × ω_r themselves."""
    x, y, z, w = qe[0], qe[1], qe[2], qe[3]
    C = ((1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)),
         (2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)),
         (2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)))
    for i in range(3):
        omega_r[i] = C[0][i] * w_ref[0] + C[1][i] * w_ref[1] + C[2][i] * w_ref[2]
        domega_r[i] = C[0][i] * wd_ref[0] + C[1][i] * wd_ref[1] + C[2][i] * wd_ref[2]
