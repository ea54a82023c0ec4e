"""Real thrusters (``sms_cli.thrusters``) in the compiled loop: one plant step cut at the firing pattern's
switching instants, each piece integrated with the base body holding the propellant mass at the piece's
midpoint, the tank emptying within a piece. The same sequence as ``sms_cli.thrusters.drive.step_drives`` for one
drive (its ``_breaks``, ``_on_at``, the cut where the tank empties) and ``propellant.Tank.set_removed``; the pattern itself (allocation by
the LP, modulation) comes from ``ThrusterDrive.command``, called by the runner at each control tick.

``thr`` is the tuple (B (6, n): base wrench [f; n] per newton, base joint frame; max_force (n,) N; mass_flow (n,)
kg/s while on; firing cycle s; propellant load kg; the loaded base body's spatial inertia (6, 6), mass kg and CoM
(3,) m; the tank's unit point-mass spatial inertia (6, 6) and position (3,) m, base joint frame).
``state`` (2,): [propellant used kg, the mass the tree's base body has lost kg].
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from sms_cli.sim.compiled import JIT
from sms_cli.sim.compiled.dynamics import rkmk4_step

USED, REMOVED = 0, 1


@njit(**JIT)
def set_removed(thr, removed, inertia, mass, com, state):
    """The tree's base body (index 0) holds the loaded body minus ``removed`` kg of propellant at the tank
    (``Tank.set_removed``: linear in the dynamic parameters)."""
    Y0, m0, c0, unit, p = thr[5], thr[6], thr[7], thr[8], thr[9]
    for a in range(6):
        for b in range(6):
            inertia[0, a, b] = Y0[a, b] - removed * unit[a, b]
    m = m0 - removed
    mass[0] = m
    for a in range(3):
        com[0, a] = (m0 * c0[a] - removed * p[a]) / m
    state[REMOVED] = removed


@njit(**JIT)
def _breaks(t, t1, t0, on, cycle):
    """The step's ends and the switching instants strictly inside (t, t1), sorted, without repeats (``_breaks``)."""
    j0 = int(math.floor((t - t0) / cycle + 1e-12))
    jn = j0 + int(math.ceil((t1 - t) / cycle)) + 2
    pts = [t, t1]
    for j in range(j0, jn):
        c = t0 + j * cycle
        if t < c < t1:
            pts.append(c)
        for i in range(on.shape[0]):
            if on[i] > 0:
                x = c + on[i]
                if t < x < t1:
                    pts.append(x)
    a = np.sort(np.array(pts))
    out = [a[0]]
    for x in a[1:]:
        if x != out[-1]:
            out.append(x)
    return out


@njit(**JIT)
def thruster_step(tree, thr, t0, on, q, v, tau, t, dt, q_new, v_new, impulse, state, work):
    """The state after the plant step [t, t + dt] (into q_new, v_new) under ``tau`` (nv, without the thrusters)
    plus the firings of the pattern (on-times ``on``, s, repeating every cycle from ``t0``); ``impulse`` (n) gets
    each thruster's impulse over the step (N s); ``state`` is updated (propellant used, the base body's mass)."""
    parent, kind, axis, place_R, place_p, inertia, leaf_IA, mass, com, armature, idx_q, idx_v = tree
    B, fmax, mdot, cycle, load = thr[0], thr[1], thr[2], thr[3], thr[4]
    n = fmax.shape[0]
    nv = v.shape[0]
    impulse[:] = 0.0
    qa, va = q.copy(), v.copy()
    tau_p = np.empty(nv)
    f = np.zeros(n)
    lit = np.zeros(n, dtype=np.bool_)
    no_Bt, no_BtB, no_e = np.zeros((6, 0)), np.zeros((6, 6)), np.zeros(0)
    no_i = np.zeros(0, dtype=np.int64)
    pts = _breaks(t, t + dt, t0, on, cycle)
    for k in range(len(pts) - 1):
        a, b = pts[k], pts[k + 1]
        h = b - a
        if h <= 0:
            continue
        tm = 0.5 * (a + b)
        m_dot = 0.0
        for i in range(n):
            lit[i] = state[USED] < load and ((tm - t0) % cycle) < on[i]
            if lit[i]:
                m_dot += mdot[i]
        if m_dot > 0 and state[USED] + m_dot * h > load:  # the tank empties in this piece
            h_burn = (load - state[USED]) / m_dot
            _piece(tree, thr, qa, va, tau, tau_p, lit, m_dot, h_burn, q_new, v_new, f, impulse, state, no_Bt, no_BtB, no_e,
                   no_i, work)
            state[USED] = load
            lit[:] = False
            _piece(tree, thr, qa, va, tau, tau_p, lit, 0.0, h - h_burn, q_new, v_new, f, impulse, state, no_Bt, no_BtB, no_e,
                   no_i, work)
        else:
            _piece(tree, thr, qa, va, tau, tau_p, lit, m_dot, h, q_new, v_new, f, impulse, state, no_Bt, no_BtB, no_e, no_i,
                   work)
    if state[USED] != state[REMOVED]:
        set_removed(thr, state[USED], inertia, mass, com, state)
    q_new[:] = qa
    v_new[:] = va


@njit(**JIT)
def _piece(tree, thr, qa, va, tau, tau_p, lit, m_dot, h, q_new, v_new, f, impulse, state, no_Bt, no_BtB, no_e, no_i, work):
    """One piece of h s with the thrusters ``lit`` (``ThrusterDrive._piece``): the base body at the mass of the
    piece's midpoint, the RKMK4 step of h from (qa, va) in place."""
    if h <= 0:
        return
    parent, kind, axis, place_R, place_p, inertia, leaf_IA, mass, com, armature, idx_q, idx_v = tree
    B, fmax = thr[0], thr[1]
    mid = state[USED] + 0.5 * m_dot * h
    if mid != state[REMOVED]:
        set_removed(thr, mid, inertia, mass, com, state)
    for i in range(fmax.shape[0]):
        f[i] = fmax[i] if lit[i] else 0.0
    for a in range(tau.shape[0]):
        tau_p[a] = tau[a]
    for r in range(6):
        s = 0.0
        for i in range(f.shape[0]):
            s += B[r, i] * f[i]
        tau_p[r] += s
    rkmk4_step(parent, kind, axis, place_R, place_p, inertia, leaf_IA, armature, idx_q, idx_v, no_Bt, no_BtB, no_e, no_e,
               no_i, no_i, no_e, no_e, no_e, qa, va, no_e, no_e, tau_p, h, q_new, v_new, no_e, no_e, work,
               no_i)  # no joint locked: the loop's signature of rkmk4_step (compiled once)
    qa[:] = q_new
    va[:] = v_new
    state[USED] += m_dot * h
    for i in range(f.shape[0]):
        impulse[i] += f[i] * h
