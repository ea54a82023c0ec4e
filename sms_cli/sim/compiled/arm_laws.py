"""Compiled (numba) arm laws: THE implementation of joint_pd (Chevallard 2019), smc (Ruggiero 2020),
computed_torque and smc_computed_torque (Caldera 2019), of the reduced joint-space model they use
(``arm_model_terms``) and of the joint waypoint reference (``joint_reference``). The Python loop's
classes (``sms_cli.sim.laws.arm``, ``plant_models.ArmDynamics``, ``references.JointProfile``) call these
kernels, with Pinocchio's mass matrix and bias forces; the compiled loop calls them with the compiled
dynamics' (``dynamics.mass_matrix``, ``dynamics.bias_forces``).

``arm_torque(code, par, wrap, q_ref, qd_ref, qdd_ref, q, qd, Mstar, hstar, out)``: joint torques (N m or
N, arm order, before the effort limits) into ``out``; errors e = q_d − q (wrapped into (−π, π] on the
``wrap`` joints), ė = q̇_d − q̇; ``par`` (ARM_PAR_ROWS × n_arm): one row per gain (layouts below);
Mstar, hstar: M* (n_arm × n_arm) and h* of the arm model (unused by the model-free laws).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from sms_cli.sim.compiled import HOT, JIT
from sms_cli.sim.compiled.attitude_laws import _sign
from sms_cli.sim.compiled.dynamics import cholesky, cholesky_solve

# law codes
JOINT_PD, JOINT_SMC, COMPUTED_TORQUE, SMC_COMPUTED_TORQUE = 0, 1, 2, 3
# parameter rows of each law
PD_KP, PD_KD, PD_FF = 0, 1, 2  # ff: 1 with rate feedforward, 0 without
SMC_K, SMC_LAM, SMC_ETA, SMC_SIGN = 0, 1, 2, 3  # sign: 1 for sign(σ), 0 for tanh
CT_KP, CT_KD = 0, 1
SCT_K1, SCT_K2, SCT_C, SCT_MU, SCT_LAM, SCT_SIGN = 0, 1, 2, 3, 4, 5
ARM_PAR_ROWS = 6
# the arm laws that need the model (M*, h*)
MODEL_LAWS = (COMPUTED_TORQUE, SMC_COMPUTED_TORQUE)


@njit(**HOT)
def _error(q_ref, q, wrap, i):
    """e_i = q_d − q, modulo 2π into (−π, π] on a continuous joint."""
    e = q_ref[i] - q[i]
    if wrap[i]:
        e = (e + math.pi) % (2.0 * math.pi) - math.pi
    return e


@njit(**JIT)
def arm_torque(code, par, wrap, q_ref, qd_ref, qdd_ref, q, qd, Mstar, hstar, out):
    """The arm law ``code``'s joint torques into ``out`` (see the module docstring):

    - JOINT_PD: τ = K_D (K_P e + ff q̇_d − q̇)
    - JOINT_SMC: σ = −(λ e + ė), τ = −k tanh(η σ) (or −k sign(σ))
    - COMPUTED_TORQUE: τ = M* (q̈_d + K_d ė + K_p e) + h*
    - SMC_COMPUTED_TORQUE: s = ė + λ e, τ = M* (q̈_d + k₁ ė + k₂ e + c tanh(μ s)) + h* (or sign(s))
    """
    n = q.shape[0]
    x = np.empty(n)
    for i in range(n):
        e = _error(q_ref, q, wrap, i)
        ed = qd_ref[i] - qd[i]
        if code == JOINT_PD:
            out[i] = par[PD_KD, i] * (par[PD_KP, i] * e + par[PD_FF, i] * qd_ref[i] - qd[i])
        elif code == JOINT_SMC:
            sig = -(par[SMC_LAM, i] * e + ed)
            sw = _sign(sig) if par[SMC_SIGN, i] != 0.0 else math.tanh(par[SMC_ETA, i] * sig)
            out[i] = -par[SMC_K, i] * sw
        elif code == COMPUTED_TORQUE:
            x[i] = qdd_ref[i] + par[CT_KD, i] * ed + par[CT_KP, i] * e
        else:
            sig = ed + par[SCT_LAM, i] * e
            sw = _sign(sig) if par[SCT_SIGN, i] != 0.0 else math.tanh(par[SCT_MU, i] * sig)
            x[i] = qdd_ref[i] + par[SCT_K1, i] * ed + par[SCT_K2, i] * e + par[SCT_C, i] * sw
    if code == COMPUTED_TORQUE or code == SMC_COMPUTED_TORQUE:
        for i in range(n):
            acc = hstar[i]
            for j in range(n):
                acc += Mstar[i, j] * x[j]
            out[i] = acc


@njit(**JIT)
def arm_model_terms(M, nb, a, p, Mstar, hstar):
    """The arm's joint-space dynamics M* q̈_a + h* = τ_a from the (augmented) mass matrix M and the
    bias nb (right-hand side τ = M q̈ + nb) when the coordinates ``p`` are free (zero generalized force)
    and all others but the arm's ``a`` are held (``plant_models.ArmDynamics``):
    M* = M_aa − M_ap M_pp⁻¹ M_pa (symmetrised), h* = n_a − M_ap M_pp⁻¹ n_p; p empty: M_aa, n_a."""
    na, k = a.shape[0], p.shape[0]
    if k == 0:
        for i in range(na):
            hstar[i] = nb[a[i]]
            for j in range(na):
                Mstar[i, j] = M[a[i], a[j]]
        return
    # Cholesky of M_pp, then X = M_pp⁻¹ [M_pa, n_p] column by column
    Mpp = np.empty((k, k))
    for i in range(k):
        for j in range(k):
            Mpp[i, j] = M[p[i], p[j]]
    L = np.zeros((k, k))
    cholesky(Mpp, k, L)
    X = np.empty((k, na + 1))
    rhs = np.empty(k)
    col = np.empty(k)
    for c in range(na + 1):
        for i in range(k):
            rhs[i] = M[p[i], a[c]] if c < na else nb[p[i]]
        cholesky_solve(L, rhs, k, col)
        for i in range(k):
            X[i, c] = col[i]
    for i in range(na):
        acc = nb[a[i]]
        for m in range(k):
            acc -= M[a[i], p[m]] * X[m, na]
        hstar[i] = acc
        for j in range(na):
            acc = M[a[i], a[j]]
            for m in range(k):
                acc -= M[a[i], p[m]] * X[m, j]
            Mstar[i, j] = acc
    for i in range(na):
        for j in range(i + 1, na):
            s = 0.5 * (Mstar[i, j] + Mstar[j, i])
            Mstar[i, j] = s
            Mstar[j, i] = s


@njit(**HOT)
def quintic(s):
    """Rest-to-rest quintic blend on s ∈ [0, 1]: (p, dp/ds, d²p/ds²) (``references.quintic``)."""
    s = min(max(s, 0.0), 1.0)
    s2 = s * s
    s3 = s2 * s
    s4 = s3 * s
    return (10.0 * s3 - 15.0 * s4 + 6.0 * s4 * s, 30.0 * s2 - 60.0 * s3 + 30.0 * s4, 60.0 * s - 180.0 * s2 + 120.0 * s3)


@njit(**JIT)
def joint_reference(times, points, step, tau, q, qd, qdd):
    """The joint reference at time tau from the phase start through the waypoints (``times`` (m+1,),
    ``points`` (m+1, n_arm), row 0 the phase's start): the segment's start point when ``step``, else
    quintic rest-to-rest segments; the last point after the last waypoint (``references.JointProfile``)."""
    n = points.shape[1]
    for k in range(1, times.shape[0]):
        t0, t1 = times[k - 1], times[k]
        if tau < t1:
            if step:
                for i in range(n):
                    q[i] = points[k - 1, i]
                    qd[i] = 0.0
                    qdd[i] = 0.0
                return
            T = t1 - t0
            p, dp, ddp = quintic((tau - t0) / T)
            for i in range(n):
                d = points[k, i] - points[k - 1, i]
                q[i] = points[k - 1, i] + p * d
                qd[i] = dp / T * d
                qdd[i] = ddp / (T * T) * d
            return
    last = times.shape[0] - 1
    for i in range(n):
        q[i] = points[last, i]
        qd[i] = 0.0
        qdd[i] = 0.0
