"""The base-mounted flexible appendages' terms of the momenta and energy (world frame; ``SystemModel.momenta``,
``energy``), shared by the compiled loops (``loop.run_ticks``, ``ndi_loop.run_ticks_ndi``) and their recording."""

from __future__ import annotations

import numpy as np
from numba import njit

from sms_cli.sim.compiled import JIT
from sms_cli.sim.compiled.dynamics import joint_transforms, momenta_energy, quat_to_matrix, workspace
from sms_cli.sim.compiled.ndi_law import augmented_mass


@njit(**JIT)
def modal_momentum_energy(q, v, eta, etadot, modal_B, neg_omega2, mass, com, oR, op, me):
    """Add the base-mounted appendages' terms to ``me`` = [p, k about the CoM, k about the origin, energy]
    of the rigid tree (world frame; ``SystemModel.momenta``, ``energy``): the modal momentum Bᵀη̇ (a
    base-frame wrench at the base origin) moved to the world, k about the rigid tree's CoM (from the
    bodies' world placements oR, op, as ``momenta_energy`` leaves them), and ½|η̇|² + (B v_b)·η̇ + ½ Σ Ω² η²."""
    ne = eta.shape[0]
    if ne == 0:
        return
    P = np.zeros(6)
    for k in range(ne):
        for a in range(6):
            P[a] += modal_B[k, a] * etadot[k]
    R = np.empty((3, 3))
    quat_to_matrix(q[3], q[4], q[5], q[6], R)
    f = np.empty(3)
    n = np.empty(3)
    for a in range(3):
        f[a] = R[a, 0] * P[0] + R[a, 1] * P[1] + R[a, 2] * P[2]
        n[a] = R[a, 0] * P[3] + R[a, 1] * P[4] + R[a, 2] * P[5]
    rx, ry, rz = q[0], q[1], q[2]
    me[0] += f[0]
    me[1] += f[1]
    me[2] += f[2]
    me[6] += n[0] + ry * f[2] - rz * f[1]
    me[7] += n[1] + rz * f[0] - rx * f[2]
    me[8] += n[2] + rx * f[1] - ry * f[0]
    c0 = c1 = c2 = 0.0
    mtot = 0.0
    for i in range(mass.shape[0]):
        m = mass[i]
        c0 += m * (op[i, 0] + oR[i, 0, 0] * com[i, 0] + oR[i, 0, 1] * com[i, 1] + oR[i, 0, 2] * com[i, 2])
        c1 += m * (op[i, 1] + oR[i, 1, 0] * com[i, 0] + oR[i, 1, 1] * com[i, 1] + oR[i, 1, 2] * com[i, 2])
        c2 += m * (op[i, 2] + oR[i, 2, 0] * com[i, 0] + oR[i, 2, 1] * com[i, 1] + oR[i, 2, 2] * com[i, 2])
        mtot += m
    c0, c1, c2 = c0 / mtot, c1 / mtot, c2 / mtot
    me[3] = me[6] - (c1 * me[2] - c2 * me[1])
    me[4] = me[7] - (c2 * me[0] - c0 * me[2])
    me[5] = me[8] - (c0 * me[1] - c1 * me[0])
    e = 0.0
    for k in range(ne):
        Bv = 0.0
        for a in range(6):
            Bv += modal_B[k, a] * v[a]
        e += 0.5 * etadot[k] * etadot[k] + Bv * etadot[k] - 0.5 * neg_omega2[k] * eta[k] * eta[k]
    me[9] += e


@njit(**JIT)
def modal_sample_momenta(parent, kind, axis, inertia, mass, com, armature, place_R, place_p, idx_q, idx_v, modal_B, neg_omega2,
                         qs, vs, etas, etadots, out, Ms):
    """[p, k about the CoM, k about the origin, energy] (world frame) of each sampled state, modes included
    (``SystemModel.momenta``, ``energy``), for the recording; with ``Ms`` (samples × nx × nx; 0 × nx × nx: not
    wanted) also the augmented mass matrices (``augmented_mass``)."""
    n = parent.shape[0]
    ws = workspace(n, qs.shape[1], vs.shape[1], etas.shape[1])
    R_rel = np.empty((n, 3, 3))
    p_rel = np.empty((n, 3))
    for s in range(qs.shape[0]):
        joint_transforms(kind, axis, place_R, place_p, idx_q, qs[s], R_rel, p_rel)
        momenta_energy(parent, kind, axis, inertia, mass, com, armature, idx_v, R_rel, p_rel, vs[s], out[s], ws)
        modal_momentum_energy(qs[s], vs[s], etas[s], etadots[s], modal_B, neg_omega2, mass, com, ws[16], ws[17], out[s])
        if Ms.shape[0]:
            augmented_mass(parent, kind, axis, inertia, armature, idx_v, R_rel, p_rel, modal_B, Ms[s])
