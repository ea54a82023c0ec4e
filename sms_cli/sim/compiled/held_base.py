"""Compiled (numba) held base (``base_mode: fixed``): the wrench the support applies to hold the base, for
the compiled loop's trace and recording. The held plant itself is the RKMK4 step with the base
coordinates 0-5 locked (``dynamics.lock_joints``, the stops' constraint), equal to
``SystemModel.forward_dynamics_fixed_base``.

Wrench [f; n] in the base frame (N, N m): the base rows of M ẍ + b at ẍ = (0, M_ff⁻¹ (τ_f − b_f)), τ the
wheel and arm torques (``SystemModel.base_reaction`` after ``forward_dynamics_fixed_base``), rigid tree.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from sms_cli.sim.compiled import JIT
from sms_cli.sim.compiled.dynamics import bias_forces, cholesky, cholesky_solve, joint_transforms, mass_matrix

BASE = np.arange(6, dtype=np.int64)  # the base's velocity coordinates, locked while it is held


@njit(**JIT)
def held_base_reaction(M, b, tau, out):
    """The holding wrench (6) into out from the mass matrix M (nv × nv), the bias forces b and the
    generalized forces tau (nv; base entries unused) at one state."""
    nv = M.shape[0]
    k = nv - 6
    A, L = np.empty((k, k)), np.empty((k, k))
    r, a = np.empty(k), np.empty(k)
    for i in range(k):
        r[i] = tau[6 + i] - b[6 + i]
        for j in range(k):
            A[i, j] = M[6 + i, 6 + j]
    cholesky(A, k, L)
    cholesky_solve(L, r, k, a)
    for i in range(6):
        acc = 0.0
        for j in range(k):
            acc += M[i, 6 + j] * a[j]
        out[i] = acc + b[i]


@njit(**JIT)
def held_base_reactions(parent, kind, axis, place_R, place_p, inertia, armature, idx_q, idx_v, wheel_v, arm_v, qs, vs,
                        tau_w, tau_m, out):
    """``held_base_reaction`` at each sampled state (rows of qs, vs) under its wheel torques tau_w and arm
    torques tau_m (rows), into the rows of out (the recording's /base/reaction)."""
    n, nv = parent.shape[0], vs.shape[1]
    R_rel, p_rel = np.empty((n, 3, 3)), np.empty((n, 3))
    M, b, tau = np.empty((nv, nv)), np.empty(nv), np.zeros(nv)
    for s in range(qs.shape[0]):
        joint_transforms(kind, axis, place_R, place_p, idx_q, qs[s], R_rel, p_rel)
        mass_matrix(parent, kind, axis, inertia, armature, idx_v, R_rel, p_rel, M)
        bias_forces(parent, kind, axis, inertia, idx_v, R_rel, p_rel, vs[s], b)
        for i in range(wheel_v.shape[0]):
            tau[wheel_v[i]] = tau_w[s, i]
        for i in range(arm_v.shape[0]):
            tau[arm_v[i]] = tau_m[s, i]
        held_base_reaction(M, b, tau, out[s])
