"""Compiled (numba) rigid-body kernels on a flattened tree (``tree.Tree``): articulated-body
forward dynamics, forward kinematics, momentum and energy, and the RKMK4 step.

Conventions are Pinocchio's, so that the results equal ``pin.aba``, ``pin.integrate`` and
``SystemModel.momenta`` to round-off (tests/test_compiled_dynamics.py): motion vectors
``[v; ω]`` and forces ``[f; n]`` linear first, body velocities in the joint frames, the
free-flyer configuration ``[x y z qx qy qz qw]`` (world position, base → world quaternion)
and its velocity in the base frame; q ⊕ θ composes on the right, ``M(q) exp6(θ)``.
No gravity (space). Arrays only, no Python objects: every function is ``@njit``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from sms_cli.sim.compiled import HOT, JIT
from sms_cli.sim.compiled.tree import FREE_FLYER, PRISMATIC, REVOLUTE, REVOLUTE_UNBOUNDED


# ----------------------------------------------------------------------------- 3-D helpers
@njit(**HOT)
def quat_to_matrix(x, y, z, w, R):
    """R (3×3) of the unit quaternion (x, y, z, w)."""
    R[0, 0] = 1.0 - 2.0 * (y * y + z * z)
    R[0, 1] = 2.0 * (x * y - z * w)
    R[0, 2] = 2.0 * (x * z + y * w)
    R[1, 0] = 2.0 * (x * y + z * w)
    R[1, 1] = 1.0 - 2.0 * (x * x + z * z)
    R[1, 2] = 2.0 * (y * z - x * w)
    R[2, 0] = 2.0 * (x * z - y * w)
    R[2, 1] = 2.0 * (y * z + x * w)
    R[2, 2] = 1.0 - 2.0 * (x * x + y * y)


@njit(**HOT)
def matrix_to_quat(R, out):
    """Quaternion (x, y, z, w) of a rotation matrix, by Eigen's algorithm (the same sign as
    ``pin.Quaternion(R)``)."""
    t = R[0, 0] + R[1, 1] + R[2, 2]
    if t > 0.0:
        s = math.sqrt(t + 1.0)
        out[3] = 0.5 * s
        s = 0.5 / s
        out[0] = (R[2, 1] - R[1, 2]) * s
        out[1] = (R[0, 2] - R[2, 0]) * s
        out[2] = (R[1, 0] - R[0, 1]) * s
        return
    i = 0
    if R[1, 1] > R[0, 0]:
        i = 1
    if R[2, 2] > R[i, i]:
        i = 2
    j = (i + 1) % 3
    k = (j + 1) % 3
    s = math.sqrt(R[i, i] - R[j, j] - R[k, k] + 1.0)
    out[i] = 0.5 * s
    s = 0.5 / s
    out[3] = (R[k, j] - R[j, k]) * s
    out[j] = (R[j, i] + R[i, j]) * s
    out[k] = (R[k, i] + R[i, k]) * s


@njit(**HOT)
def axis_rotation(ax, angle_cos, angle_sin, R):
    """Rotation by an angle (given by its cosine and sine) about the unit axis ax."""
    c, s = angle_cos, angle_sin
    t = 1.0 - c
    x, y, z = ax[0], ax[1], ax[2]
    R[0, 0] = c + t * x * x
    R[0, 1] = t * x * y - s * z
    R[0, 2] = t * x * z + s * y
    R[1, 0] = t * x * y + s * z
    R[1, 1] = c + t * y * y
    R[1, 2] = t * y * z - s * x
    R[2, 0] = t * x * z - s * y
    R[2, 1] = t * y * z + s * x
    R[2, 2] = c + t * z * z


@njit(**JIT)
def cross(a, b, out):
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]


# ----------------------------------------------------------------------------- kinematics
@njit(**HOT)
def compose(R1, p1, R2, p2, R_out, p_out):
    """(R_out, p_out) = (R1, p1) · (R2, p2): rotation R1 R2, translation p1 + R1 p2."""
    for a in range(3):
        acc = p1[a]
        for c in range(3):
            acc += R1[a, c] * p2[c]
        p_out[a] = acc
        for b in range(3):
            acc = 0.0
            for c in range(3):
                acc += R1[a, c] * R2[c, b]
            R_out[a, b] = acc


@njit(**HOT)
def joint_transforms(kind, axis, place_R, place_p, idx_q, q, R_out, p_out):
    """Placement of each joint frame in its parent joint frame (the root's: in the world):
    the joint's fixed placement composed with its motion (rotation Rj, translation tj); Rj is built
    in R_out[i] and multiplied by the placement in place (no scratch array to allocate)."""
    for i in range(kind.shape[0]):
        k = kind[i]
        iq = idx_q[i]
        Rj = R_out[i]
        t0 = t1 = t2 = 0.0
        if k == FREE_FLYER:
            quat_to_matrix(q[iq + 3], q[iq + 4], q[iq + 5], q[iq + 6], Rj)
            t0, t1, t2 = q[iq], q[iq + 1], q[iq + 2]
        elif k == PRISMATIC:
            axis_rotation(axis[i], 1.0, 0.0, Rj)  # identity
            t0, t1, t2 = axis[i, 0] * q[iq], axis[i, 1] * q[iq], axis[i, 2] * q[iq]
        elif k == REVOLUTE:
            axis_rotation(axis[i], math.cos(q[iq]), math.sin(q[iq]), Rj)
        else:  # REVOLUTE_UNBOUNDED: (cos, sin)
            axis_rotation(axis[i], q[iq], q[iq + 1], Rj)
        PR, Pp = place_R[i], place_p[i]
        for a in range(3):  # p_out = Pp + PR tj, R_out = PR Rj (column by column, in place)
            p_out[i, a] = Pp[a] + PR[a, 0] * t0 + PR[a, 1] * t1 + PR[a, 2] * t2
        for b in range(3):
            c0, c1, c2 = Rj[0, b], Rj[1, b], Rj[2, b]
            for a in range(3):
                Rj[a, b] = PR[a, 0] * c0 + PR[a, 1] * c1 + PR[a, 2] * c2


@njit(**HOT)
def world_placements(parent, R_rel, p_rel, oR, op):
    """World placement of each joint frame from the parent-relative ones (parents come first)."""
    for i in range(parent.shape[0]):
        pi = parent[i]
        if pi < 0:  # element loops, not slice assignment: no broadcast check to compile
            for a in range(3):
                op[i, a] = p_rel[i, a]
                for b in range(3):
                    oR[i, a, b] = R_rel[i, a, b]
        else:
            compose(oR[pi], op[pi], R_rel[i], p_rel[i], oR[i], op[i])


@njit(**JIT)
def frame_poses(oR, op, f_joint, f_R, f_p, out):
    """World poses [x y z qx qy qz qw] of frames placed (f_R, f_p) in joints f_joint (−1: the world)."""
    R = np.empty((3, 3))
    p = np.empty(3)
    quat = np.empty(4)
    for k in range(f_joint.shape[0]):
        j = f_joint[k]
        if j < 0:
            for a in range(3):
                p[a] = f_p[k, a]
                for b in range(3):
                    R[a, b] = f_R[k, a, b]
        else:
            compose(oR[j], op[j], f_R[k], f_p[k], R, p)
        matrix_to_quat(R, quat)
        for a in range(3):
            out[k, a] = p[a]
        for a in range(4):
            out[k, 3 + a] = quat[a]


@njit(**JIT)
def relative_poses(world, parent, out):
    """Pose of each frame in its parent frame (row ``parent[k]``, −1: the world), from world
    poses [x y z qx qy qz qw]: translation R_pᵀ (r_c − r_p), rotation q_p* ⊗ q_c
    (``sms_cli.recording.frames.RelativePoses``)."""
    for k in range(world.shape[0]):
        p = parent[k]
        if p < 0:
            for a in range(7):
                out[k, a] = world[k, a]
            continue
        ux, uy, uz, w = -world[p, 3], -world[p, 4], -world[p, 5], world[p, 6]
        dx, dy, dz = world[k, 0] - world[p, 0], world[k, 1] - world[p, 1], world[k, 2] - world[p, 2]
        tx, ty, tz = 2.0 * (uy * dz - uz * dy), 2.0 * (uz * dx - ux * dz), 2.0 * (ux * dy - uy * dx)
        out[k, 0] = dx + w * tx + (uy * tz - uz * ty)
        out[k, 1] = dy + w * ty + (uz * tx - ux * tz)
        out[k, 2] = dz + w * tz + (ux * ty - uy * tx)
        qx, qy, qz, qw = world[k, 3], world[k, 4], world[k, 5], world[k, 6]
        out[k, 3] = w * qx + qw * ux + (uy * qz - uz * qy)
        out[k, 4] = w * qy + qw * uy + (uz * qx - ux * qz)
        out[k, 5] = w * qz + qw * uz + (ux * qy - uy * qx)
        out[k, 6] = w * qw - ux * qx - uy * qy - uz * qz


# ----------------------------------------------------------------------------- spatial algebra
@njit(**HOT)
def motion_act_inv(R, p, m, out):
    """(R, p)⁻¹ acting on motion m (parent coordinates → child): [Rᵀ(v − p×ω); Rᵀω]."""
    v0 = m[0] - (p[1] * m[5] - p[2] * m[4])
    v1 = m[1] - (p[2] * m[3] - p[0] * m[5])
    v2 = m[2] - (p[0] * m[4] - p[1] * m[3])
    for a in range(3):
        out[a] = R[0, a] * v0 + R[1, a] * v1 + R[2, a] * v2
        out[3 + a] = R[0, a] * m[3] + R[1, a] * m[4] + R[2, a] * m[5]


@njit(**HOT)
def force_act(R, p, f, out):
    """(R, p) acting on force f (child coordinates → parent): [R f; R n + p × R f]."""
    for a in range(3):
        out[a] = R[a, 0] * f[0] + R[a, 1] * f[1] + R[a, 2] * f[2]
        out[3 + a] = R[a, 0] * f[3] + R[a, 1] * f[4] + R[a, 2] * f[5]
    out[3] += p[1] * out[2] - p[2] * out[1]
    out[4] += p[2] * out[0] - p[0] * out[2]
    out[5] += p[0] * out[1] - p[1] * out[0]


@njit(**HOT)
def motion_cross(v, m, out):
    """v × m = [ω×m_v + v×m_ω; ω×m_ω]."""
    out[0] = v[4] * m[2] - v[5] * m[1] + v[1] * m[5] - v[2] * m[4]
    out[1] = v[5] * m[0] - v[3] * m[2] + v[2] * m[3] - v[0] * m[5]
    out[2] = v[3] * m[1] - v[4] * m[0] + v[0] * m[4] - v[1] * m[3]
    out[3] = v[4] * m[5] - v[5] * m[4]
    out[4] = v[5] * m[3] - v[3] * m[5]
    out[5] = v[3] * m[4] - v[4] * m[3]


@njit(**HOT)
def force_cross(v, f, out):
    """v ×* f = [ω×f; ω×n + v×f]."""
    out[0] = v[4] * f[2] - v[5] * f[1]
    out[1] = v[5] * f[0] - v[3] * f[2]
    out[2] = v[3] * f[1] - v[4] * f[0]
    out[3] = v[4] * f[5] - v[5] * f[4] + v[1] * f[2] - v[2] * f[1]
    out[4] = v[5] * f[3] - v[3] * f[5] + v[2] * f[0] - v[0] * f[2]
    out[5] = v[3] * f[4] - v[4] * f[3] + v[0] * f[1] - v[1] * f[0]


@njit(**HOT)
def add_inertia_to_parent(R, p, Ia, J, K, out):
    """out += Xᵀ Ia X for X = motion_act_inv(R, p): a symmetric 6×6 inertia moved to the parent frame,
    on the LOWER triangle of out only (its upper triangle is left as is; Ia is read whole). By 3×3
    blocks, Ia = [[A, Dᵀ], [D, C]] (A, C symmetric): rotated A' = R A Rᵀ, D' = R D Rᵀ, C' = R C Rᵀ
    (the symmetric ones on one triangle), then with P = [p]× and E = A' P, F = D' P
    Xᵀ Ia X = [[A', ·], [D' + P A', C' − F − Fᵀ − P E]], D' + P A' = D' − Eᵀ (J, K: 6×6 scratch)."""
    for a in range(3):  # K = R · (A, D, C)
        for b in range(3):
            K[a, b] = R[a, 0] * Ia[0, b] + R[a, 1] * Ia[1, b] + R[a, 2] * Ia[2, b]
            K[3 + a, b] = R[a, 0] * Ia[3, b] + R[a, 1] * Ia[4, b] + R[a, 2] * Ia[5, b]
            K[3 + a, 3 + b] = R[a, 0] * Ia[3, 3 + b] + R[a, 1] * Ia[4, 3 + b] + R[a, 2] * Ia[5, 3 + b]
    for a in range(3):  # J = K · Rᵀ: A', C' on their lower triangles (A' mirrored), D' whole
        for b in range(3):
            J[3 + a, b] = K[3 + a, 0] * R[b, 0] + K[3 + a, 1] * R[b, 1] + K[3 + a, 2] * R[b, 2]
        for b in range(a + 1):
            x = K[a, 0] * R[b, 0] + K[a, 1] * R[b, 1] + K[a, 2] * R[b, 2]
            J[a, b] = x
            J[b, a] = x
            J[3 + a, 3 + b] = K[3 + a, 3] * R[b, 0] + K[3 + a, 4] * R[b, 1] + K[3 + a, 5] * R[b, 2]
    p0, p1, p2 = p[0], p[1], p[2]
    for a in range(3):  # row vectors times P: (x P) = (x1 p2 − x2 p1, x2 p0 − x0 p2, x0 p1 − x1 p0)
        for blk in range(2):  # K[:3, :3] = E = A' P, K[3:, :3] = F = D' P
            x0, x1, x2 = J[3 * blk + a, 0], J[3 * blk + a, 1], J[3 * blk + a, 2]
            K[3 * blk + a, 0] = x1 * p2 - x2 * p1
            K[3 * blk + a, 1] = x2 * p0 - x0 * p2
            K[3 * blk + a, 2] = x0 * p1 - x1 * p0
    for a in range(3):
        for b in range(a + 1):
            out[a, b] += J[a, b]
        for b in range(3):
            out[3 + b, a] += J[3 + b, a] - K[a, b]
    for b in range(3):
        y0, y1, y2 = K[0, b], K[1, b], K[2, b]  # column b of E; P y = p × y
        py = (p1 * y2 - p2 * y1, p2 * y0 - p0 * y2, p0 * y1 - p1 * y0)
        for a in range(b, 3):
            out[3 + a, 3 + b] += J[3 + a, 3 + b] - K[3 + a, b] - K[3 + b, a] - py[a]


@njit(**HOT)
def mirror_lower(M):
    """Copy the lower triangle of the 6×6 M onto its upper triangle (M symmetric)."""
    for a in range(6):
        for b in range(a):
            M[b, a] = M[a, b]


@njit(**HOT)
def _subspace(kind, axis, S):
    """Motion subspace (6,) of a 1-DoF joint in its frame."""
    S[:] = 0.0
    if kind == PRISMATIC:
        S[0], S[1], S[2] = axis[0], axis[1], axis[2]
    else:
        S[3], S[4], S[5] = axis[0], axis[1], axis[2]


# ----------------------------------------------------------------------------- dynamics
@njit(**JIT)
def workspace(n, nq, nv, ne=0):
    """Scratch arrays for n bodies (nq, nv, ne modes), reused by every kernel below (no allocation
    in the hot loop). Entries 25-33 are the joint-stop kernels' (``lock_joints``)."""
    return (np.empty((n, 6)), np.zeros((n, 6)), np.empty((n, 6, 6)), np.empty((n, 6)), np.zeros((n, 6)),
            np.ones(n), np.zeros(n), np.empty((n, 6)), np.empty((n, 3, 3)), np.empty((n, 3)),
            np.empty((6, 6)), np.empty((6, 6)), np.empty((6, 6)), np.empty(6), np.empty(6), np.empty(6),
            np.empty((n, 3, 3)), np.empty((n, 3)), np.empty((8, nv)), np.empty(nq),
            np.empty((10, ne)), np.empty(nv), np.zeros((6, 6)), np.zeros(6), np.empty(6),
            np.zeros(nv), np.empty(nv), np.empty(nv), np.zeros((6, 6)), np.zeros(6), np.empty((nv + ne, nv)),
            np.empty((nv, nv)), np.empty((nv, nv)), np.empty(nv))


@njit(**HOT)
def body_velocities(parent, kind, axis, R_rel, p_rel, idx_v, v, vel):
    """Spatial velocity of each body in its joint frame."""
    n = parent.shape[0]
    for i in range(n):
        iv = idx_v[i]
        if kind[i] == FREE_FLYER:
            for a in range(6):
                vel[i, a] = v[iv + a]
            continue
        motion_act_inv(R_rel[i], p_rel[i], vel[parent[i]], vel[i])
        off = 0 if kind[i] == PRISMATIC else 3
        for a in range(3):
            vel[i, off + a] += axis[i, a] * v[iv]


@njit(**HOT)
def _solve_spd6(A, b, L, out):
    """out = A⁻¹ b for a symmetric positive definite 6×6 A, read on its lower triangle (Cholesky
    A = L Lᵀ; L is scratch and holds the inverse of its diagonal: 6 divisions, not 27)."""
    for j in range(6):
        d = A[j, j]
        for k in range(j):
            d -= L[j, k] * L[j, k]
        d_inv = 1.0 / math.sqrt(d)
        L[j, j] = d_inv
        for i in range(j + 1, 6):
            x = A[i, j]
            for k in range(j):
                x -= L[i, k] * L[j, k]
            L[i, j] = x * d_inv
    for i in range(6):
        x = b[i]
        for k in range(i):
            x -= L[i, k] * out[k]
        out[i] = x * L[i, i]
    for i in range(5, -1, -1):
        x = out[i]
        for k in range(i + 1, 6):
            x -= L[k, i] * out[k]
        out[i] = x * L[i, i]


@njit(**HOT)
def aba(parent, kind, axis, inertia, leaf_IA, armature, idx_v, R_rel, p_rel, v, tau, root_dI, root_f, vdot, ws):
    """Featherstone's articulated-body algorithm (Pinocchio's ``aba`` with a free-flyer root and
    no gravity): vdot (nv) for the joint transforms (R_rel, p_rel) of ``joint_transforms``.
    ``root_dI`` (6×6) is added to the root body's inertia and ``root_f`` (6) to its bias force,
    both in the root frame: the mass matrix becomes H + [root_dI on the base block] and the
    right-hand side τ − nle − [root_f; 0] (zeros for a plain rigid tree). ``leaf_IA`` gives the
    constant parent-frame articulated inertia of symmetric leaves (``tree.flatten``; NaN: none)."""
    vel, c, IA, pA, U, D, u, acc6 = ws[0], ws[1], ws[2], ws[3], ws[4], ws[5], ws[6], ws[7]
    X, Ia, XtIa, tmp, pa = ws[10], ws[11], ws[12], ws[13], ws[14]  # (ws[15] is no longer used)
    n = parent.shape[0]
    body_velocities(parent, kind, axis, R_rel, p_rel, idx_v, v, vel)
    for i in range(n):
        for a in range(6):
            acc = 0.0
            for b in range(6):
                acc += inertia[i, a, b] * vel[i, b]
            tmp[a] = acc
            for b in range(a + 1):  # IA: the lower triangle (symmetric)
                IA[i, a, b] = inertia[i, a, b]
        force_cross(vel[i], tmp, pA[i])
        if kind[i] == FREE_FLYER:
            for a in range(6):
                pA[i, a] += root_f[a]
                for b in range(a + 1):
                    IA[i, a, b] += root_dI[a, b]
        else:  # c = v × S q̇, S q̇ = the axis times q̇ in the linear (prismatic) or angular rows
            qd = v[idx_v[i]]
            w0, w1, w2 = axis[i, 0] * qd, axis[i, 1] * qd, axis[i, 2] * qd
            v0, v1, v2, o0, o1, o2 = vel[i, 0], vel[i, 1], vel[i, 2], vel[i, 3], vel[i, 4], vel[i, 5]
            if kind[i] == PRISMATIC:  # [ω × w; 0]
                c[i, 0], c[i, 1], c[i, 2] = o1 * w2 - o2 * w1, o2 * w0 - o0 * w2, o0 * w1 - o1 * w0
                c[i, 3], c[i, 4], c[i, 5] = 0.0, 0.0, 0.0
            else:  # [v × w; ω × w]
                c[i, 0], c[i, 1], c[i, 2] = v1 * w2 - v2 * w1, v2 * w0 - v0 * w2, v0 * w1 - v1 * w0
                c[i, 3], c[i, 4], c[i, 5] = o1 * w2 - o2 * w1, o2 * w0 - o0 * w2, o0 * w1 - o1 * w0
    for i in range(n - 1, -1, -1):  # the children add to the lower triangle of IA (symmetric) only
        if kind[i] == FREE_FLYER:
            continue
        iv = idx_v[i]
        IAi = IA[i]
        mirror_lower(IAi)
        off = 0 if kind[i] == PRISMATIC else 3  # S = the unit axis in the linear or the angular rows
        ax0, ax1, ax2 = axis[i, 0], axis[i, 1], axis[i, 2]
        for a in range(6):
            U[i, a] = IAi[a, off] * ax0 + IAi[a, off + 1] * ax1 + IAi[a, off + 2] * ax2
        d = armature[iv] + ax0 * U[i, off] + ax1 * U[i, off + 1] + ax2 * U[i, off + 2]
        D[i] = d
        ui = tau[iv] - (ax0 * pA[i, off] + ax1 * pA[i, off + 1] + ax2 * pA[i, off + 2])
        u[i] = ui
        pi = parent[i]
        d_inv = 1.0 / d
        for a in range(6):  # U D⁻¹ (Pinocchio's UDinv)
            tmp[a] = U[i, a] * d_inv
        for a in range(6):
            for b in range(a + 1):
                x = IAi[a, b] - tmp[a] * U[i, b]
                Ia[a, b] = x
                Ia[b, a] = x
        for a in range(6):
            acc = pA[i, a] + tmp[a] * ui
            for b in range(6):
                acc += Ia[a, b] * c[i, b]
            pa[a] = acc
        # parent += Xᵀ Ia X (X: parent motion → child motion), pA_parent += X* pa
        if math.isnan(leaf_IA[i, 0, 0]):
            add_inertia_to_parent(R_rel[i], p_rel[i], Ia, XtIa, X, IA[pi])
        else:
            for a in range(6):
                for b in range(a + 1):
                    IA[pi, a, b] += leaf_IA[i, a, b]
        force_act(R_rel[i], p_rel[i], pa, tmp)
        for a in range(6):
            pA[pi, a] += tmp[a]
    for i in range(n):
        iv = idx_v[i]
        if kind[i] == FREE_FLYER:
            for a in range(6):
                tmp[a] = tau[iv + a] - pA[i, a]
            _solve_spd6(IA[i], tmp, X, acc6[i])
            for a in range(6):
                vdot[iv + a] = acc6[i, a]
            continue
        motion_act_inv(R_rel[i], p_rel[i], acc6[parent[i]], acc6[i])
        for a in range(6):
            acc6[i, a] += c[i, a]
        ua = 0.0
        for a in range(6):
            ua += U[i, a] * acc6[i, a]
        qdd = (u[i] - ua) / D[i]
        vdot[iv] = qdd
        off = 0 if kind[i] == PRISMATIC else 3
        for a in range(3):
            acc6[i, off + a] += axis[i, a] * qdd


@njit(**JIT)
def momenta_energy(parent, kind, axis, inertia, mass, com, armature, idx_v, R_rel, p_rel, v, out, ws):
    """out = [p (3), k about the CoM (3), k about the world origin (3), kinetic energy (J)], world frame."""
    vel, oR, op, f, fw = ws[0], ws[16], ws[17], ws[13], ws[14]
    n = parent.shape[0]
    body_velocities(parent, kind, axis, R_rel, p_rel, idx_v, v, vel)
    world_placements(parent, R_rel, p_rel, oR, op)
    h0 = h1 = h2 = h3 = h4 = h5 = 0.0
    c0 = c1 = c2 = 0.0
    mtot = 0.0
    energy = 0.0
    for i in range(n):
        for a in range(6):
            acc = 0.0
            for b in range(6):
                acc += inertia[i, a, b] * vel[i, b]
            f[a] = acc
            energy += 0.5 * vel[i, a] * acc
        force_act(oR[i], op[i], f, fw)
        h0 += fw[0]
        h1 += fw[1]
        h2 += fw[2]
        h3 += fw[3]
        h4 += fw[4]
        h5 += fw[5]
        m = mass[i]
        c0 += m * (op[i, 0] + oR[i, 0, 0] * com[i, 0] + oR[i, 0, 1] * com[i, 1] + oR[i, 0, 2] * com[i, 2])
        c1 += m * (op[i, 1] + oR[i, 1, 0] * com[i, 0] + oR[i, 1, 1] * com[i, 1] + oR[i, 1, 2] * com[i, 2])
        c2 += m * (op[i, 2] + oR[i, 2, 0] * com[i, 0] + oR[i, 2, 1] * com[i, 1] + oR[i, 2, 2] * com[i, 2])
        mtot += m
    for k in range(armature.shape[0]):
        energy += 0.5 * armature[k] * v[k] * v[k]
    c0, c1, c2 = c0 / mtot, c1 / mtot, c2 / mtot
    out[0], out[1], out[2] = h0, h1, h2
    out[3] = h3 - (c1 * h2 - c2 * h1)
    out[4] = h4 - (c2 * h0 - c0 * h2)
    out[5] = h5 - (c0 * h1 - c1 * h0)
    out[6], out[7], out[8] = h3, h4, h5
    out[9] = energy


# ----------------------------------------------------------------------------- integration

aba_call = njit(**JIT)(aba.py_func)  # the same ABA behind a plain call for callers off the hot path (not inlined there)


@njit(**HOT)
def quat_exp_mul(q, w, out):
    """out = q ⊗ exp(w/2) (xyzw; w a rotation vector in the frame of q), normalised."""
    ang = math.sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])
    if ang < 1e-8:
        s = 0.5 - ang * ang / 48.0
        c = 1.0 - ang * ang / 8.0
    else:
        s = math.sin(0.5 * ang) / ang
        c = math.cos(0.5 * ang)
    bx, by, bz, bw = s * w[0], s * w[1], s * w[2], c
    ax, ay, az, aw = q[0], q[1], q[2], q[3]
    x = aw * bx + ax * bw + ay * bz - az * by
    y = aw * by - ax * bz + ay * bw + az * bx
    z = aw * bz + ax * by - ay * bx + az * bw
    ww = aw * bw - ax * bx - ay * by - az * bz
    nrm = math.sqrt(x * x + y * y + z * z + ww * ww)
    out[0], out[1], out[2], out[3] = x / nrm, y / nrm, z / nrm, ww / nrm


@njit(**HOT)
def integrate(kind, axis, idx_q, idx_v, q, theta, out):
    """out = q ⊕ θ (Pinocchio's ``integrate``: right composition with exp6 for the free flyer)."""
    n = kind.shape[0]
    for i in range(n):
        iq, iv = idx_q[i], idx_v[i]
        k = kind[i]
        if k == FREE_FLYER:
            # M0 exp6([ρ; φ]): p = p0 + R0 V(φ) ρ, quaternion q0 ⊗ exp(φ)
            px, py, pz = theta[iv], theta[iv + 1], theta[iv + 2]
            wx, wy, wz = theta[iv + 3], theta[iv + 4], theta[iv + 5]
            t2 = wx * wx + wy * wy + wz * wz
            t = math.sqrt(t2)
            if t < 1e-4:
                a = 0.5 - t2 / 24.0
                b = 1.0 / 6.0 - t2 / 120.0
            else:
                a = (1.0 - math.cos(t)) / t2
                b = (t - math.sin(t)) / (t2 * t)
            # V ρ = ρ + a φ×ρ + b φ×(φ×ρ)
            c0 = wy * pz - wz * py
            c1 = wz * px - wx * pz
            c2 = wx * py - wy * px
            d0 = wy * c2 - wz * c1
            d1 = wz * c0 - wx * c2
            d2 = wx * c1 - wy * c0
            l0 = px + a * c0 + b * d0
            l1 = py + a * c1 + b * d1
            l2 = pz + a * c2 + b * d2
            x, y, z, w = q[iq + 3], q[iq + 4], q[iq + 5], q[iq + 6]  # R l, R of quat_to_matrix
            out[iq] = q[iq] + (1.0 - 2.0 * (y * y + z * z)) * l0 + 2.0 * (x * y - z * w) * l1 + 2.0 * (x * z + y * w) * l2
            out[iq + 1] = q[iq + 1] + 2.0 * (x * y + z * w) * l0 + (1.0 - 2.0 * (x * x + z * z)) * l1 + 2.0 * (y * z - x * w) * l2
            out[iq + 2] = q[iq + 2] + 2.0 * (x * z - y * w) * l0 + 2.0 * (y * z + x * w) * l1 + (1.0 - 2.0 * (x * x + y * y)) * l2
            quat_exp_mul(q[iq + 3:iq + 7], theta[iv + 3:iv + 6], out[iq + 3:iq + 7])
        elif k == REVOLUTE_UNBOUNDED:
            ca, sa = math.cos(theta[iv]), math.sin(theta[iv])
            c0, s0 = q[iq], q[iq + 1]
            out[iq] = c0 * ca - s0 * sa
            out[iq + 1] = s0 * ca + c0 * sa
        else:
            out[iq] = q[iq] + theta[iv]


@njit(**HOT)
def dexpinv_neg(theta, v, out):
    """dexp⁻¹_{−θ}(v) = v + ½[θ, v] + 1/12 [θ, [θ, v]] on the free-flyer block (first 6),
    identity on the joints (``sms_cli.dynamics.integrator._dexpinv_neg``)."""
    for a in range(v.shape[0]):
        out[a] = v[a]
    r0, r1, r2, p0, p1, p2 = theta[0], theta[1], theta[2], theta[3], theta[4], theta[5]
    u0, u1, u2, w0, w1, w2 = v[0], v[1], v[2], v[3], v[4], v[5]
    a0 = p1 * u2 - p2 * u1 + r1 * w2 - r2 * w1
    a1 = p2 * u0 - p0 * u2 + r2 * w0 - r0 * w2
    a2 = p0 * u1 - p1 * u0 + r0 * w1 - r1 * w0
    b0 = p1 * w2 - p2 * w1
    b1 = p2 * w0 - p0 * w2
    b2 = p0 * w1 - p1 * w0
    out[0] = u0 + 0.5 * a0 + (p1 * a2 - p2 * a1 + r1 * b2 - r2 * b1) / 12.0
    out[1] = u1 + 0.5 * a1 + (p2 * a0 - p0 * a2 + r2 * b0 - r0 * b2) / 12.0
    out[2] = u2 + 0.5 * a2 + (p0 * a1 - p1 * a0 + r0 * b1 - r1 * b0) / 12.0
    out[3] = w0 + 0.5 * b0 + (p1 * b2 - p2 * b1) / 12.0
    out[4] = w1 + 0.5 * b1 + (p2 * b0 - p0 * b2) / 12.0
    out[5] = w2 + 0.5 * b2 + (p0 * b1 - p1 * b0) / 12.0


@njit(**HOT)
def hybrid_dynamics(parent, kind, axis, place_R, place_p, inertia, leaf_IA, armature, idx_q, idx_v, modal_Bt, modal_BtB,
                    neg_omega2, neg_2zo, spring_v, spring_q, spring_k, spring_c, spring_rest,
                    q, v, eta, etad, tau, vdot, etadd, ws):
    """(v̇, η̈) of the hybrid model with appendages on the base (``SystemModel.forward_dynamics``):
    (H − BᵀB) v̇ = τ − nle − [Bᵀ r_η + v_b ×* (Bᵀ η̇); 0] − springs, η̈ = r_η − B v̇_b,
    r_η = −Ω² η − 2ζΩ η̇; the constant −BᵀB enters ABA as the root's inertia and the modal terms
    as its bias force. ``modal_Bt`` is Bᵀ (6 × ne); ne = 0 and no springs is the rigid tree."""
    ne = eta.shape[0]
    tau_eff, root_dI, root_f, P = ws[21], ws[22], ws[23], ws[24]
    r_eta = ws[20][9]
    for a in range(v.shape[0]):
        tau_eff[a] = tau[a]
    for k in range(spring_v.shape[0]):
        iv = spring_v[k]
        tau_eff[iv] -= spring_k[k] * (q[spring_q[k]] - spring_rest[k]) + spring_c[k] * v[iv]
    if ne:
        for k in range(ne):
            r_eta[k] = neg_omega2[k] * eta[k] + neg_2zo[k] * etad[k]
        for a in range(6):
            acc_p = 0.0
            acc_r = 0.0
            for k in range(ne):
                acc_p += modal_Bt[a, k] * etad[k]
                acc_r += modal_Bt[a, k] * r_eta[k]
            P[a] = acc_p
            root_f[a] = acc_r
            for b in range(6):
                root_dI[a, b] = -modal_BtB[a, b]
        tmp = ws[13]
        force_cross(v[0:6], P, tmp)  # v_b ×* P: the modal momentum carried by the moving base
        for a in range(6):
            root_f[a] += tmp[a]
    R_rel, p_rel = ws[8], ws[9]
    joint_transforms(kind, axis, place_R, place_p, idx_q, q, R_rel, p_rel)
    aba(parent, kind, axis, inertia, leaf_IA, armature, idx_v, R_rel, p_rel, v, tau_eff, root_dI, root_f, vdot, ws)
    for k in range(ne):
        acc = r_eta[k]
        for a in range(6):
            acc -= modal_Bt[a, k] * vdot[a]
        etadd[k] = acc


@njit(**HOT)
def rk4_advance(stage, dt, v, acc, kk, th, vs):
    """RKMK4 after stage 0, 1 or 2: the next stage's tangent step th = c·v (stage 0) or c·k (the stage's dexp⁻¹-corrected
    slope kk) and velocity vs = v + c·acc[stage], c = dt/2, dt/2, dt."""
    c = 0.5 * dt if stage < 2 else dt
    for a in range(v.shape[0]):
        th[a] = c * (v[a] if stage == 0 else kk[a])
        vs[a] = v[a] + c * acc[stage, a]


@njit(**HOT)
def rk4_combine(dt, v, ksum, kk, acc, th, v_out):
    """RKMK4's final tangent step th = dt/6·(v + 2(k2 + k3) + k4) (``ksum`` = k2 + k3, ``kk`` = k4) and velocity
    v_out = v + dt/6·(a1 + 2(a2 + a3) + a4), the stages' accelerations the rows of ``acc``."""
    c = dt / 6.0
    for a in range(v.shape[0]):
        th[a] = c * (v[a] + 2.0 * ksum[a] + kk[a])
        v_out[a] = v[a] + c * (acc[0, a] + 2.0 * (acc[1, a] + acc[2, a]) + acc[3, a])


@njit(**JIT)
def rkmk4_step(parent, kind, axis, place_R, place_p, inertia, leaf_IA, armature, idx_q, idx_v, modal_Bt, modal_BtB,
               neg_omega2, neg_2zo, spring_v, spring_q, spring_k, spring_c, spring_rest,
               q, v, eta, etad, tau, dt, q_out, v_out, eta_out, etad_out, ws, locked=None):
    """One RKMK4 step of size dt (s) under the held generalized forces τ
    (``sms_cli.dynamics.integrator.rkmk4_step``): the configuration moves on the manifold with the
    dexp⁻¹ correction, velocities and modal states are plain vectors. The four stages are one loop
    so that the inlined dynamics is compiled once. The joints ``locked`` (velocity indices, int64;
    None or empty: none) are held at zero acceleration at every stage (``lock_joints``: joint stops)."""
    nv, ne = v.shape[0], eta.shape[0]
    h = 0.5 * dt
    st = ws[18]
    acc, th, vs, kk, ksum = st[0:4], st[4], st[5], st[6], st[7]
    md = ws[20]  # rows 0-3: η̈ per stage, 4: η at the stage, 5: η̇ at the stage, 6-7: weighted slope sums
    qs = ws[19]
    for a in range(q.shape[0]):
        qs[a] = q[a]
    for a in range(nv):
        vs[a] = v[a]
        ksum[a] = 0.0
    for k in range(ne):
        md[4, k] = eta[k]
        md[5, k] = etad[k]
        md[6, k] = 0.0
        md[7, k] = 0.0
    for stage in range(4):
        if stage > 0:
            integrate(kind, axis, idx_q, idx_v, q, th, qs)
        hybrid_dynamics(parent, kind, axis, place_R, place_p, inertia, leaf_IA, armature, idx_q, idx_v, modal_Bt, modal_BtB,
                        neg_omega2, neg_2zo, spring_v, spring_q, spring_k, spring_c, spring_rest,
                        qs, vs, md[4], md[5], tau, acc[stage], md[stage], ws)
        if locked is not None and locked.shape[0] > 0:
            lock_joints(parent, kind, axis, inertia, leaf_IA, armature, idx_v, ws[8], ws[9], modal_Bt, locked,
                        acc[stage], md[stage], ws)
        w = 1.0 if stage == 0 or stage == 3 else 2.0
        for k in range(ne):
            md[6, k] += w * md[5, k]
            md[7, k] += w * md[stage, k]
        if stage > 0:
            dexpinv_neg(th, vs, kk)  # k2, k3, k4
            if stage < 3:
                for a in range(nv):
                    ksum[a] += kk[a]  # k2 + k3
        if stage < 3:
            rk4_advance(stage, dt, v, acc, kk, th, vs)
            c = h if stage < 2 else dt
            for k in range(ne):
                e_next = eta[k] + c * md[5, k]
                md[5, k] = etad[k] + c * md[stage, k]
                md[4, k] = e_next
    rk4_combine(dt, v, ksum, kk, acc, th, v_out)
    c = dt / 6.0
    for k in range(ne):
        eta_out[k] = eta[k] + c * md[6, k]
        etad_out[k] = etad[k] + c * md[7, k]
    integrate(kind, axis, idx_q, idx_v, q, th, q_out)




# ----------------------------------------------------------------------------- joint stops
# The contact law of sms_cli.dynamics.joint_stops (which holds the rest of the stop law, for both
# engines): columns of M⁻¹ and the acceleration of locked joints held at zero.
@njit(**JIT)
def _minv_columns(parent, kind, axis, inertia, leaf_IA, armature, idx_v, R_rel, p_rel, modal_Bt, cols, G, ws):
    """G[:, j] = column cols[j] of the inverse augmented mass matrix (rows nv..: the modal part) at the
    joint transforms (R_rel, p_rel): ABA at zero velocity on a unit generalized force, the base-mounted
    modes as the root inertia −BᵀB, then η̈ = −B v̇_b (``SystemModel`` module docstring)."""
    nv, ne = armature.shape[0], modal_Bt.shape[1]
    zero_v, unit, col, root_dI, zero_f = ws[25], ws[26], ws[27], ws[28], ws[29]  # zero_v, zero_f stay zero
    for a in range(6):
        for b in range(6):
            acc = 0.0
            for k in range(ne):
                acc += modal_Bt[a, k] * modal_Bt[b, k]
            root_dI[a, b] = -acc
    for j in range(cols.shape[0]):
        for a in range(nv):
            unit[a] = 0.0
        unit[cols[j]] = 1.0
        aba_call(parent, kind, axis, inertia, leaf_IA, armature, idx_v, R_rel, p_rel, zero_v, unit, root_dI, zero_f, col, ws)
        for a in range(nv):
            G[a, j] = col[a]
        for k in range(ne):
            acc = 0.0
            for a in range(6):
                acc -= modal_Bt[a, k] * col[a]
            G[nv + k, j] = acc


@njit(**JIT)
def cholesky(A, k, L):
    """L[:k, :k] lower triangular with L Lᵀ = A[:k, :k] (symmetric positive definite A)."""
    for j in range(k):
        d = A[j, j]
        for m in range(j):
            d -= L[j, m] * L[j, m]
        d = math.sqrt(d)
        L[j, j] = d
        for i in range(j + 1, k):
            x = A[i, j]
            for m in range(j):
                x -= L[i, m] * L[j, m]
            L[i, j] = x / d


@njit(**JIT)
def cholesky_solve(L, b, k, out):
    """out[:k] = (L Lᵀ)⁻¹ b[:k], L from ``cholesky``."""
    for i in range(k):
        x = b[i]
        for m in range(i):
            x -= L[i, m] * out[m]
        out[i] = x / L[i, i]
    for i in range(k - 1, -1, -1):
        x = out[i]
        for m in range(i + 1, k):
            x -= L[m, i] * out[m]
        out[i] = x / L[i, i]


@njit(**JIT)
def cholesky_solve_columns(A, k, X, L, col):
    """X[:k] ← A⁻¹ X[:k] in place, column by column, for the symmetric positive definite leading k×k block of A
    (``cholesky`` into the k×k scratch L, read on A's lower triangle); ``col`` (k,) scratch."""
    cholesky(A, k, L)
    for j in range(X.shape[1]):
        for a in range(k):
            col[a] = X[a, j]
        cholesky_solve(L, col, k, col)
        for a in range(k):
            X[a, j] = col[a]


@njit(**JIT)
def _solve_spd(A, b, k, L, out):
    """out[:k] = A[:k, :k]⁻¹ b[:k] for a symmetric positive definite A (Cholesky; L is k×k scratch)."""
    cholesky(A, k, L)
    cholesky_solve(L, b, k, out)


@njit(**JIT)
def lock_joints(parent, kind, axis, inertia, leaf_IA, armature, idx_v, R_rel, p_rel, modal_Bt, locked, vdot, etadd, ws):
    """The contact law (``joint_stops.lock_accelerations``): add the generalized forces λ on the joints
    ``locked`` that make their accelerations zero, a = a_free + M⁻¹ e_L λ with (M⁻¹)_LL λ = −(a_free)_L;
    vdot (nv) and etadd (ne) hold a_free on entry, a on return."""
    nv, ne, k = vdot.shape[0], etadd.shape[0], locked.shape[0]
    G, A, L, lam = ws[30], ws[31], ws[32], ws[33]
    _minv_columns(parent, kind, axis, inertia, leaf_IA, armature, idx_v, R_rel, p_rel, modal_Bt, locked, G, ws)
    rhs = ws[21]  # free: hybrid_dynamics is done with τ_eff
    for i in range(k):
        rhs[i] = -vdot[locked[i]]
        for j in range(k):
            A[i, j] = G[locked[i], j]
    _solve_spd(A, rhs, k, L, lam)
    for a in range(nv):
        acc = 0.0
        for j in range(k):
            acc += G[a, j] * lam[j]
        vdot[a] += acc
    for m in range(ne):
        acc = 0.0
        for j in range(k):
            acc += G[nv + m, j] * lam[j]
        etadd[m] += acc


@njit(**JIT)
def accelerations(parent, kind, axis, place_R, place_p, inertia, leaf_IA, armature, idx_q, idx_v, modal_Bt, modal_BtB,
                  neg_omega2, neg_2zo, spring_v, spring_q, spring_k, spring_c, spring_rest,
                  q, v, eta, etad, tau, vdot, etadd, ws):
    """``hybrid_dynamics`` behind a plain call: the free accelerations (v̇, η̈), for the stop law's
    contact decisions."""
    hybrid_dynamics(parent, kind, axis, place_R, place_p, inertia, leaf_IA, armature, idx_q, idx_v, modal_Bt, modal_BtB,
                    neg_omega2, neg_2zo, spring_v, spring_q, spring_k, spring_c, spring_rest,
                    q, v, eta, etad, tau, vdot, etadd, ws)


@njit(**JIT)
def inverse_mass_columns(parent, kind, axis, place_R, place_p, inertia, leaf_IA, armature, idx_q, idx_v, modal_Bt, q, cols, G,
                         ws):
    """G (nv + ne × len(cols)) = columns cols of the inverse augmented mass matrix at q (stop impulses)."""
    R_rel, p_rel = ws[8], ws[9]
    joint_transforms(kind, axis, place_R, place_p, idx_q, q, R_rel, p_rel)
    _minv_columns(parent, kind, axis, inertia, leaf_IA, armature, idx_v, R_rel, p_rel, modal_Bt, cols, G, ws)


# ----------------------------------------------------------------------------- joint-space terms (arm laws)
@njit(**JIT)
def mass_matrix(parent, kind, axis, inertia, armature, idx_v, R_rel, p_rel, M):
    """M (nv×nv) = the joint-space inertia H(q) with the rotor armature on its diagonal (Pinocchio's
    ``crba``, both triangles), by the composite-rigid-body algorithm at the joint transforms (R_rel, p_rel)."""
    n, nv = parent.shape[0], armature.shape[0]
    Ic = np.empty((n, 6, 6))
    for i in range(n):
        for a in range(6):
            for b in range(6):
                Ic[i, a, b] = inertia[i, a, b]
    J, K = np.empty((6, 6)), np.empty((6, 6))
    for i in range(n - 1, -1, -1):  # the children add to the lower triangle of Ic (symmetric) only
        mirror_lower(Ic[i])
        if parent[i] >= 0:
            add_inertia_to_parent(R_rel[i], p_rel[i], Ic[i], J, K, Ic[parent[i]])
    for a in range(nv):
        for b in range(nv):
            M[a, b] = 0.0
    F = np.empty((6, 6))  # rows: the force columns I_c S of joint i, carried to the ancestors
    Ft = np.empty(6)
    S = np.empty(6)
    for i in range(n):
        ni = 6 if kind[i] == FREE_FLYER else 1
        if ni == 6:
            for c in range(6):
                for a in range(6):
                    F[c, a] = Ic[i, a, c]
        else:
            _subspace(kind[i], axis[i], S)
            for a in range(6):
                acc = 0.0
                for b in range(6):
                    acc += Ic[i, a, b] * S[b]
                F[0, a] = acc
        j = i
        while True:
            for c in range(ni):
                col = idx_v[i] + c
                if kind[j] == FREE_FLYER:
                    for r in range(6):
                        M[idx_v[j] + r, col] = F[c, r]
                        M[col, idx_v[j] + r] = F[c, r]
                else:
                    _subspace(kind[j], axis[j], S)
                    acc = 0.0
                    for r in range(6):
                        acc += S[r] * F[c, r]
                    M[idx_v[j], col] = acc
                    M[col, idx_v[j]] = acc
            if parent[j] < 0:
                break
            for c in range(ni):
                force_act(R_rel[j], p_rel[j], F[c], Ft)
                for a in range(6):
                    F[c, a] = Ft[a]
            j = parent[j]
    for k in range(nv):
        M[k, k] += armature[k]


@njit(**JIT)
def bias_forces(parent, kind, axis, inertia, idx_v, R_rel, p_rel, v, out):
    """out (nv) = the bias forces C(q, v) v at zero acceleration (Pinocchio's ``nonLinearEffects``, no
    gravity), by recursive Newton-Euler at the joint transforms (R_rel, p_rel)."""
    n = parent.shape[0]
    vel = np.empty((n, 6))
    acc = np.zeros((n, 6))
    f = np.empty((n, 6))
    S = np.empty(6)
    m = np.empty(6)
    tmp = np.empty(6)
    body_velocities(parent, kind, axis, R_rel, p_rel, idx_v, v, vel)
    for i in range(n):
        if kind[i] != FREE_FLYER:
            motion_act_inv(R_rel[i], p_rel[i], acc[parent[i]], acc[i])
            _subspace(kind[i], axis[i], S)
            qd = v[idx_v[i]]
            for a in range(6):
                m[a] = S[a] * qd
            motion_cross(vel[i], m, tmp)
            for a in range(6):
                acc[i, a] += tmp[a]
        for a in range(6):
            x = 0.0
            for b in range(6):
                x += inertia[i, a, b] * vel[i, b]
            m[a] = x
        force_cross(vel[i], m, tmp)
        for a in range(6):
            x = tmp[a]
            for b in range(6):
                x += inertia[i, a, b] * acc[i, b]
            f[i, a] = x
    for i in range(n - 1, -1, -1):
        if kind[i] == FREE_FLYER:
            for a in range(6):
                out[idx_v[i] + a] = f[i, a]
        else:
            _subspace(kind[i], axis[i], S)
            x = 0.0
            for a in range(6):
                x += S[a] * f[i, a]
            out[idx_v[i]] = x
        if parent[i] >= 0:
            force_act(R_rel[i], p_rel[i], f[i], tmp)
            for a in range(6):
                f[parent[i], a] += tmp[a]
