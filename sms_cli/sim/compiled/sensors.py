"""Sensor noise and bias (``simulation.sensors``): THE implementation of the measurement a control law sees.
The Python loop's ``sms_cli.sim.sensors.Sensors.measure`` and the compiled loops (``loop.run_ticks``,
``ndi_loop.run_ticks_ndi``) call ``measure_state`` at every control tick.

Parameters ``par`` (``SENS_*`` columns; ``sensor_parameters``): the gyro's σ (rad/s) and bias (3, rad/s, base
frame), the attitude's σ (rad) and bias (3, rad, a rotation vector in the base frame), whether the attitude is
perturbed (1.0: a nonzero σ or bias), the joints' σ (rad or m, and rad/s or m/s for the rates) and bias (one
per arm joint, added to the angles and to the rates alike).

The tick's normals ``noise`` (K = 3 [gyro σ > 0] + 3 [attitude σ > 0] + 2 n_arm [joints σ > 0]) are drawn in
Python, in this order (gyro, attitude, joint angles, joint rates; only the sensors with σ > 0), from the
mission's ``np.random.default_rng(seed)``: one (ticks × K) draw gives the same numbers as ticks draws of K.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from sms_cli.sim.compiled import JIT
from sms_cli.sim.compiled.profiles import quat_mul_exp

SENS_GYRO_SIGMA, SENS_GYRO_BIAS, SENS_ATT_SIGMA, SENS_ATT_BIAS, SENS_ATT_ON, SENS_JOINT_SIGMA, SENS_JOINT_BIAS = 0, 1, 4, 5, 8, 9, 10


def sensor_parameters(spec, n_arm: int) -> np.ndarray:
    """``measure_state``'s ``par`` (SENS_JOINT_BIAS + n_arm) from a ``SensorsSpec``: scalar biases broadcast to
    the three axes and to every arm joint (a vector of three on the joints needs three joints)."""
    par = np.zeros(SENS_JOINT_BIAS + n_arm)
    par[SENS_GYRO_SIGMA] = spec.gyro.noise
    par[SENS_GYRO_BIAS:SENS_GYRO_BIAS + 3] = np.broadcast_to(np.asarray(spec.gyro.bias, float), (3,))
    par[SENS_ATT_SIGMA] = spec.attitude.noise
    att_bias = np.broadcast_to(np.asarray(spec.attitude.bias, float), (3,))
    par[SENS_ATT_BIAS:SENS_ATT_BIAS + 3] = att_bias
    par[SENS_ATT_ON] = float(spec.attitude.noise > 0 or bool(np.any(att_bias != 0)))
    par[SENS_JOINT_SIGMA] = spec.joints.noise
    par[SENS_JOINT_BIAS:] = np.broadcast_to(np.asarray(spec.joints.bias, float), (n_arm,))
    return par


def noise_width(spec, n_arm: int) -> int:
    """K, the normals one tick draws (see the module docstring)."""
    return 3 * (spec.gyro.noise > 0) + 3 * (spec.attitude.noise > 0) + 2 * n_arm * (spec.joints.noise > 0)


@njit(**JIT)
def measure_state(par, noise, arm_q, arm_v, q, v, q_s, v_s):
    """(q_s, v_s) = (q, v) as the sensors measure them, the other coordinates copied: base rate ω (v[3:6],
    base frame) + bias + σ n, base attitude (q[3:7], xyzw) ⊗ exp(bias + σ n) (``profiles.quat_mul_exp``), arm
    angles q[arm_q] and rates v[arm_v] + bias + σ n; n the tick's normals ``noise`` (K, module docstring)."""
    for a in range(q.shape[0]):
        q_s[a] = q[a]
    for a in range(v.shape[0]):
        v_s[a] = v[a]
    off = 0
    sg = par[SENS_GYRO_SIGMA]
    for a in range(3):
        x = v[3 + a] + par[SENS_GYRO_BIAS + a]
        if sg > 0.0:
            x = x + sg * noise[off + a]
        v_s[3 + a] = x
    if sg > 0.0:
        off += 3
    sa = par[SENS_ATT_SIGMA]
    if par[SENS_ATT_ON] != 0.0:
        r0, r1, r2 = par[SENS_ATT_BIAS], par[SENS_ATT_BIAS + 1], par[SENS_ATT_BIAS + 2]
        if sa > 0.0:
            r0, r1, r2 = r0 + sa * noise[off], r1 + sa * noise[off + 1], r2 + sa * noise[off + 2]
        quat_mul_exp(q[3], q[4], q[5], q[6], r0, r1, r2, q_s[3:7])
    if sa > 0.0:
        off += 3
    n = arm_q.shape[0]
    sj = par[SENS_JOINT_SIGMA]
    for i in range(n):
        x = q[arm_q[i]] + par[SENS_JOINT_BIAS + i]
        if sj > 0.0:
            x = x + sj * noise[off + i]
        q_s[arm_q[i]] = x
    if sj > 0.0:
        off += n
    for i in range(n):
        x = v[arm_v[i]] + par[SENS_JOINT_BIAS + i]
        if sj > 0.0:
            x = x + sj * noise[off + i]
        v_s[arm_v[i]] = x
