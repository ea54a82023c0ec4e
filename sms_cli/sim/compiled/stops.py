"""Compiled (numba) joint stops for the compiled loop: the stop law of ``sms_cli.dynamics.joint_stops``
(``JointStops.step``: contacts decided at the step's start, the step with the locked joints held, then
the impulses of the joints that arrived) on a rigid tree, with its events in an array.

The stop table (``joint_stops.stop_table``) comes as arrays: for stop joint k, ``sj_v[k]``, ``sj_q[k]``
(velocity and configuration indices), ``sj_lower[k]``, ``sj_upper[k]``; its state ``side`` (0 free,
UPPER/LOWER: locked on that stop), ``rebound`` and ``since`` lives between calls. Events are rows of
``ev``: [t, kind (EV_ARRIVAL, EV_RELEASE), k, side, limit, rate, rate_after, penetration, impulse,
time_on_stop_s]; ``ev_n[0]`` counts them.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from sms_cli.sim.compiled import JIT
from sms_cli.sim.compiled.dynamics import _minv_columns, accelerations, joint_transforms, lock_joints, rkmk4_step

UPPER, LOWER = 1, -1
EV_ARRIVAL, EV_RELEASE = 0, 1
EV_COLS = 10
_BASE = np.arange(6, dtype=np.int64)  # the base's velocity coordinates (a held base)


@njit(**JIT)
def _nonzero(x):
    """The indices j with x[j] != 0, in increasing order (int64)."""
    n = 0
    for j in range(x.shape[0]):
        if x[j] != 0:
            n += 1
    out = np.empty(n, dtype=np.int64)
    n = 0
    for j in range(x.shape[0]):
        if x[j] != 0:
            out[n] = j
            n += 1
    return out


@njit(**JIT)
def _solve(A, b, out):
    """out = A⁻¹ b (Gaussian elimination with partial pivoting; A, b are not changed)."""
    k = b.shape[0]
    U = A.copy()
    y = b.copy()
    for c in range(k):
        piv = c
        for r in range(c + 1, k):
            if abs(U[r, c]) > abs(U[piv, c]):
                piv = r
        if piv != c:
            for j in range(k):
                U[c, j], U[piv, j] = U[piv, j], U[c, j]
            y[c], y[piv] = y[piv], y[c]
        for r in range(c + 1, k):
            f = U[r, c] / U[c, c]
            for j in range(c, k):
                U[r, j] -= f * U[c, j]
            y[r] -= f * y[c]
    for i in range(k - 1, -1, -1):
        s = y[i]
        for j in range(i + 1, k):
            s -= U[i, j] * out[j]
        out[i] = s / U[i, i]


@njit(**JIT)
def complementarity(W, b, mu):
    """μ ≥ 0 with r = W μ − b ≥ 0 and μᵀ r = 0 into ``mu`` (``joint_stops.complementarity``: Murty's
    least-index principal pivoting). Returns False if the pivoting did not terminate."""
    k = b.shape[0]
    active = np.empty(k, dtype=np.bool_)
    scale = 1e-300
    for i in range(k):
        active[i] = b[i] > 0
        scale = max(scale, abs(b[i]))
    tol = 1e-13 * scale
    r = np.empty(k)
    for _ in range(4 * (1 << min(k, 10)) + 10):
        for i in range(k):
            mu[i] = 0.0
        idx = np.nonzero(active)[0]
        m = idx.shape[0]
        if m:
            Wa = np.empty((m, m))
            ba = np.empty(m)
            xa = np.empty(m)
            for i in range(m):
                ba[i] = b[idx[i]]
                for j in range(m):
                    Wa[i, j] = W[idx[i], idx[j]]
            _solve(Wa, ba, xa)
            for i in range(m):
                mu[idx[i]] = xa[i]
        bad = -1
        for i in range(k):
            acc = 0.0
            for j in range(k):
                acc += W[i, j] * mu[j]
            r[i] = acc - b[i]
        for i in range(k):
            if (active[i] and mu[i] < -tol) or (not active[i] and r[i] < -tol):
                bad = i
                break
        if bad < 0:
            for i in range(k):
                mu[i] = max(mu[i], 0.0)
            return True
        active[bad] = not active[bad]
    return False


@njit(**JIT)
def _event(ev, ev_n, t, kind, k, side, limit, rate, rate_after, pen, impulse, on_stop):
    row = ev[ev_n[0]]
    row[0], row[1], row[2], row[3], row[4] = t, kind, k, side, limit
    row[5], row[6], row[7], row[8], row[9] = rate, rate_after, pen, impulse, on_stop
    ev_n[0] += 1


@njit(**JIT)
def _beyond(q, sj_q, sj_lower, sj_upper, k):
    """UPPER or LOWER when stop joint k is at or beyond that limit at q, else 0."""
    x = q[sj_q[k]]
    if x >= sj_upper[k]:
        return UPPER
    if x <= sj_lower[k]:
        return LOWER
    return 0


@njit(**JIT)
def _penetration(q, sj_q, sj_lower, sj_upper, k):
    x = q[sj_q[k]]
    return max(0.0, max(x - sj_upper[k], sj_lower[k] - x))


@njit(**JIT)
def _minv(tree_a, modal_Bt, q, cols, ws, held):
    """Columns ``cols`` of the inverse augmented mass matrix at q ((nv + n_η) × len(cols)) on the tree ``tree_a``
    (the plant tree's arrays) with the base-mounted modes ``modal_Bt`` (6 × n_η; none: 6 × 0); ``held``: of
    the inverse of its free block (base rows ≈ 0; ``PinocchioPlant.inverse_mass_columns``), as the inverse
    projected on the held base: G − G_·b (G_bb)⁻¹ G_b·, G the columns of the base and of ``cols``."""
    parent, kind, axis, place_R, place_p, inertia, leaf_IA, armature, idx_q, idx_v = tree_a
    nv = armature.shape[0]
    R_rel, p_rel = ws[8], ws[9]
    joint_transforms(kind, axis, place_R, place_p, idx_q, q, R_rel, p_rel)
    k, nx = cols.shape[0], nv + modal_Bt.shape[1]
    if not held:
        G = np.empty((nx, k))
        _minv_columns(parent, kind, axis, inertia, leaf_IA, armature, idx_v, R_rel, p_rel, modal_Bt, cols, G, ws)
        return G
    all_cols = np.empty(6 + k, dtype=np.int64)
    for i in range(6):
        all_cols[i] = i
    for i in range(k):
        all_cols[6 + i] = cols[i]
    Gall = np.empty((nx, 6 + k))
    _minv_columns(parent, kind, axis, inertia, leaf_IA, armature, idx_v, R_rel, p_rel, modal_Bt, all_cols, Gall, ws)
    Gbb, x, y = np.empty((6, 6)), np.empty(6), np.empty(6)
    for a in range(6):
        for b in range(6):
            Gbb[a, b] = Gall[a, b]
    G = np.empty((nx, k))
    for j in range(k):
        for a in range(6):
            y[a] = Gall[a, 6 + j]
        _solve(Gbb, y, x)
        for r in range(nx):
            acc = Gall[r, 6 + j]
            for a in range(6):
                acc -= Gall[r, a] * x[a]
            G[r, j] = acc
    return G


@njit(**JIT)
def stop_step(tree_a, sj_v, sj_q, sj_lower, sj_upper, restitution, side, rebound, since, q, v, tau, dt, t, q_out, v_out,
              on_time, pen_max, ev, ev_n, ws, modal, eta, etadot, eta_out, etadot_out, held):
    """One plant step of dt from time t under the stop law (``JointStops.step``): contacts decided at (q, v),
    the RKMK4 step with the locked joints held, the arrivals' impulses on (q_out, v_out) and on the modal
    rates etadot_out. ``modal`` = (Bᵀ, BᵀB, −Ω², −2ζΩ) of the base-mounted modes (``CompiledPlant``; none:
    6×0, zeros, empty; eta, etadot and their outputs then empty). ``on_time`` and
    ``pen_max`` (per stop joint) accumulate the time on stop and the largest penetration after the step.
    ``held``: the base is held too (``PinocchioPlant(fixed=True)``: its coordinates 0-5 locked throughout).
    Returns False if a complementarity problem did not terminate."""
    parent, kind, axis, place_R, place_p, inertia, leaf_IA, armature, idx_q, idx_v = tree_a
    nv = v.shape[0]
    ns = sj_v.shape[0]
    # empty arrays as views (no allocation in the common step: no joint on its stop, none arriving)
    none_f, none_i = sj_lower[:0], sj_v[:0]
    modal_Bt, modal_BtB, neg_omega2, neg_2zo = modal
    # contacts: the locked joints whose contact force pushes at (q, v)
    on_stop = False
    for j in range(ns):
        if side[j] != 0:
            on_stop = True
    locked = _nonzero(side) if on_stop else none_i
    n_locked = locked.shape[0]
    if n_locked:
        vd = np.empty(nv)
        etadd = np.empty(eta.shape[0])
        accelerations(parent, kind, axis, place_R, place_p, inertia, leaf_IA, armature, idx_q, idx_v, modal_Bt, modal_BtB,
                      neg_omega2, neg_2zo, none_i, none_i, none_f, none_f, none_f, q, v, eta, etadot, tau, vd, etadd, ws)
        if held:  # the held base's free accelerations (forward_dynamics_fixed_base)
            lock_joints(parent, kind, axis, inertia, leaf_IA, armature, idx_v, ws[8], ws[9], modal_Bt, _BASE, vd, etadd, ws)
        cols = np.empty(n_locked, dtype=np.int64)
        for i in range(n_locked):
            cols[i] = sj_v[locked[i]]
        G = _minv(tree_a, modal_Bt, q, cols, ws, held)
        W = np.empty((n_locked, n_locked))
        b = np.empty(n_locked)
        for i in range(n_locked):
            oi = float(side[locked[i]])
            b[i] = oi * vd[cols[i]]
            for k in range(n_locked):
                W[i, k] = oi * G[cols[i], k] * float(side[locked[k]])
        mu = np.empty(n_locked)
        if not complementarity(W, b, mu):
            return False
        keep = 0
        for i in range(n_locked):
            j = locked[i]
            if mu[i] <= 0.0:
                _event(ev, ev_n, t, EV_RELEASE, j, side[j], 0.0, 0.0, 0.0, 0.0, 0.0, t - since[j])
                side[j] = 0
            else:
                locked[keep] = j
                keep += 1
        n_locked = keep
    nb = 6 if held else 0
    lock_v = np.empty(nb + n_locked, dtype=np.int64) if nb + n_locked else none_i
    for i in range(nb):
        lock_v[i] = i
    for i in range(n_locked):
        lock_v[nb + i] = sj_v[locked[i]]
    rkmk4_step(parent, kind, axis, place_R, place_p, inertia, leaf_IA, armature, idx_q, idx_v, modal_Bt, modal_BtB, neg_omega2,
               neg_2zo, none_i, none_i, none_f, none_f, none_f, q, v, eta, etadot, tau, dt, q_out, v_out, eta_out, etadot_out, ws,
               lock_v)
    t1 = t + dt
    for i in range(n_locked):
        on_time[locked[i]] += dt
    # arrivals (JointStops._arrivals)
    any_arriving = False
    for j in range(ns):
        bj = _beyond(q_out, sj_q, sj_lower, sj_upper, j)
        if side[j] == 0 and bj != 0 and bj * v_out[sj_v[j]] > 0.0:
            any_arriving = True
    if any_arriving:
        beyond = np.zeros(ns, dtype=np.int64)
        sd = np.zeros(ns, dtype=np.int64)
        for j in range(ns):
            beyond[j] = _beyond(q_out, sj_q, sj_lower, sj_upper, j)
            sd[j] = side[j] if side[j] != 0 else beyond[j]
        S = _nonzero(sd)
        m = S.shape[0]
        o = np.empty(m)
        u0 = np.empty(m)
        rate = np.empty(m)
        bounce = np.zeros(m, dtype=np.bool_)
        b = np.empty(m)
        cols = np.empty(m, dtype=np.int64)
        umax = 0.0
        for i in range(m):
            j = S[i]
            o[i] = float(sd[j])
            rate[i] = v_out[sj_v[j]]
            u0[i] = o[i] * rate[i]
            umax = max(umax, abs(u0[i]))
            arr = side[j] == 0 and beyond[j] != 0 and beyond[j] * rate[i] > 0.0
            bounce[i] = arr and not rebound[j] and restitution > 0.0
            b[i] = u0[i] - (-restitution * u0[i] if bounce[i] else 0.0)
            cols[i] = sj_v[j]
        G = _minv(tree_a, modal_Bt, q_out, cols, ws, held)
        W = np.empty((m, m))
        for i in range(m):
            for k in range(m):
                W[i, k] = o[i] * G[cols[i], k] * o[k]
        mu = np.empty(m)
        if not complementarity(W, b, mu):
            return False
        for a in range(G.shape[0]):
            acc = 0.0
            for k in range(m):
                acc += G[a, k] * (-o[k] * mu[k])
            if a < nv:
                v_out[a] += acc
            else:
                etadot_out[a - nv] += acc
        tol = 1e-9 * umax
        for i in range(m):
            j = S[i]
            u1 = o[i] * v_out[cols[i]]
            if side[j] != 0:
                if u1 < -tol:
                    _event(ev, ev_n, t1, EV_RELEASE, j, side[j], 0.0, 0.0, 0.0, 0.0, 0.0, t1 - since[j])
                    side[j] = 0
                continue
            if mu[i] <= 0.0:
                continue
            limit = sj_upper[j] if o[i] == UPPER else sj_lower[j]
            _event(ev, ev_n, t1, EV_ARRIVAL, j, o[i], limit, rate[i], v_out[cols[i]], abs(q_out[sj_q[j]] - limit),
                   -o[i] * mu[i], 0.0)
            if bounce[i]:
                rebound[j] = True
            else:
                side[j] = int(o[i])
                since[j] = t1
    for j in range(ns):
        pen = _penetration(q_out, sj_q, sj_lower, sj_upper, j)
        pen_max[j] = max(pen_max[j], pen)
        if not pen > 0.0:
            rebound[j] = False
    return True
