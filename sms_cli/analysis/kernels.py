"""Compiled (numba) per-sample kernels of the workspace indices: the one implementation of every
index formula of ``sms_cli.analysis.indices`` (which documents the indices and their frames).

:func:`block_indices` takes a block of mass matrices and LOCAL end-effector Jacobians (the
Pinocchio terms, ``IndexKernel.pinocchio_terms``) and fills, per sample, the pose, the
free-floating maps (centroidal momentum columns A, generalized Jacobians J*) and the index
values, in one pass over the block (a few hundred flops per sample on 3×3 to 6×n matrices,
instead of some sixty numpy calls over stacks of small matrices). Each sample is computed on
its own, in float64, so the values do not depend on the block size, the block's other samples
or the number of threads: ``IndexKernel`` runs the parts of a block on threads (the kernel
releases the GIL; ``SMS_ANALYSIS_THREADS``, default: the cores this process may use).

Closed forms for 3×3 (determinant, adjugate inverse, Smith's eigenvalues), LAPACK (numba's
``np.linalg``) for other sizes; the rare ill-conditioned null-motion sample uses ``pinv``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

JIT = {"cache": True, "nogil": True, "error_model": "numpy"}

#: Columns of the ``out`` array of :func:`block_indices` (NaN where not computed).
OUT = ("ee_x", "ee_y", "ee_z", "ee_roll", "ee_pitch", "ee_yaw", "mu_fixed", "fixed_cond", "mu_gjm", "gjm_cond",
       "mu_dyn", "K_m", "K_r", "mu_scal_lin", "mu_null_lin", "mu_null_ang", "mu_fixed_scaled", "h_arm_max", "h_ratio")
COL = {c: i for i, c in enumerate(OUT)}
#: Flags of :func:`block_indices` (bits of ``what``).
FREE, MANIP, DYN, BASE, NULL, MOMENTUM, ZONOTOPE = 1, 2, 4, 8, 16, 32, 64


# ----------------------------------------------------------------------------- helpers on slots
# Work matrices are slots of one scratch array S (slots × D × D) per thread, addressed by index: no
# array (not even a view) is made per sample. A matrix "x, r, c" is S[x, :r, :c].
@njit(**JIT)
def det3(S, x):
    """Determinant of the 3×3 matrix S[x] (cofactors along the first row)."""
    return (S[x, 0, 0] * (S[x, 1, 1] * S[x, 2, 2] - S[x, 1, 2] * S[x, 2, 1])
            - S[x, 0, 1] * (S[x, 1, 0] * S[x, 2, 2] - S[x, 1, 2] * S[x, 2, 0])
            + S[x, 0, 2] * (S[x, 1, 0] * S[x, 2, 1] - S[x, 1, 1] * S[x, 2, 0]))


@njit(**JIT)
def inv3(S, x, y):
    """S[y] = S[x]⁻¹ (3×3, adjugate over determinant)."""
    for j in range(3):
        a, b = (j + 1) % 3, (j + 2) % 3
        # column j of the adjugate: row a × row b
        S[y, 0, j] = S[x, a, 1] * S[x, b, 2] - S[x, a, 2] * S[x, b, 1]
        S[y, 1, j] = S[x, a, 2] * S[x, b, 0] - S[x, a, 0] * S[x, b, 2]
        S[y, 2, j] = S[x, a, 0] * S[x, b, 1] - S[x, a, 1] * S[x, b, 0]
    det = S[x, 0, 0] * S[y, 0, 0] + S[x, 0, 1] * S[y, 1, 0] + S[x, 0, 2] * S[y, 2, 0]
    for i in range(3):
        for j in range(3):
            S[y, i, j] /= det


@njit(**JIT)
def eig_sym3(S, x):
    """Smallest and largest eigenvalues of the symmetric 3×3 matrix S[x] (Smith 1961)."""
    q = (S[x, 0, 0] + S[x, 1, 1] + S[x, 2, 2]) / 3.0
    p1 = S[x, 0, 1] ** 2 + S[x, 0, 2] ** 2 + S[x, 1, 2] ** 2
    p2 = (S[x, 0, 0] - q) ** 2 + (S[x, 1, 1] - q) ** 2 + (S[x, 2, 2] - q) ** 2 + 2.0 * p1
    p = math.sqrt(p2 / 6.0)
    if not p > 0:
        return q, q
    b00, b11, b22 = (S[x, 0, 0] - q) / p, (S[x, 1, 1] - q) / p, (S[x, 2, 2] - q) / p
    b01, b02, b12 = S[x, 0, 1] / p, S[x, 0, 2] / p, S[x, 1, 2] / p
    b10, b20, b21 = S[x, 1, 0] / p, S[x, 2, 0] / p, S[x, 2, 1] / p
    det = b00 * (b11 * b22 - b12 * b21) - b01 * (b10 * b22 - b12 * b20) + b02 * (b10 * b21 - b11 * b20)
    r = min(max(det / 2.0, -1.0), 1.0)
    phi = math.acos(r) / 3.0
    return q + 2.0 * p * math.cos(phi + 2.0 * math.pi / 3.0), q + 2.0 * p * math.cos(phi)


@njit(**JIT)
def mm(S, a, b, y, r, k, c):
    """S[y, :r, :c] = S[a, :r, :k] @ S[b, :k, :c]."""
    for i in range(r):
        for j in range(c):
            s = 0.0
            for l in range(k):
                s += S[a, i, l] * S[b, l, j]
            S[y, i, j] = s


@njit(**JIT)
def mmt(S, a, b, y, r, k, c):
    """S[y, :r, :c] = S[a, :r, :k] @ S[b, :c, :k]ᵀ."""
    for i in range(r):
        for j in range(c):
            s = 0.0
            for l in range(k):
                s += S[a, i, l] * S[b, j, l]
            S[y, i, j] = s


@njit(**JIT)
def gram(S, x, r, c, g):
    """S[g] = the smaller Gram matrix of S[x, :r, :c] (X Xᵀ if r ≤ c, else Xᵀ X); returns its size."""
    if r <= c:
        mmt(S, x, x, g, r, c, r)
        return r
    for i in range(c):
        for j in range(c):
            s = 0.0
            for l in range(r):
                s += S[x, l, i] * S[x, l, j]
            S[g, i, j] = s
    return c


@njit(**JIT)
def mu_of_gram(S, g, m):
    """sqrt(det S[g, :m, :m]) clipped at 0 (closed form for 3×3; 1 for an empty matrix)."""
    if m == 3:
        d = det3(S, g)
    elif m == 0:
        d = 1.0
    else:
        d = np.linalg.det(S[g, :m, :m].copy())
    return math.sqrt(max(d, 0.0))


@njit(**JIT)
def manipulability(S, x, r, c, g):
    """μ of X = S[x, :r, :c]: the product of the min(r, c) singular values = sqrt(det) of the smaller
    Gram matrix (0 when rank-deficient or empty); |det X| for 3×3. S[g]: scratch."""
    if r == 0 or c == 0:
        return 0.0
    if r == 3 and c == 3:
        return abs(det3(S, x))
    return mu_of_gram(S, g, gram(S, x, r, c, g))


@njit(**JIT)
def cond_of_gram(S, g, m):
    """σ_min/σ_max of the matrix whose Gram matrix is S[g, :m, :m] (0 for a zero or empty matrix)."""
    if m == 0:
        return 0.0
    if m == 3:
        lo, hi = eig_sym3(S, g)
    else:
        ev = np.linalg.eigvalsh(S[g, :m, :m].copy())
        lo, hi = ev[0], ev[m - 1]
    if not hi > 0:
        return 0.0
    return math.sqrt(max(lo, 0.0) / hi)


@njit(**JIT)
def cross_cols(S, c, x, y, n):
    """S[y, :3, j] = c × S[x, :3, j] for j < n (c: a 3-vector)."""
    for j in range(n):
        x0, x1, x2 = S[x, 0, j], S[x, 1, j], S[x, 2, j]
        S[y, 0, j] = c[1] * x2 - c[2] * x1
        S[y, 1, j] = c[2] * x0 - c[0] * x2
        S[y, 2, j] = c[0] * x1 - c[1] * x0


@njit(**JIT)
def manipulability_stack(X):
    """μ of each matrix of a stack (k×r×c)."""
    k, r, c = X.shape
    D = max(r, c, 1)
    S = np.empty((2, D, D))
    out = np.empty(k)
    for s in range(k):
        S[0, :r, :c] = X[s]
        out[s] = manipulability(S, 0, r, c, 1)
    return out


# ----------------------------------------------------------------------------- null motion, momentum zonotope
@njit(**JIT)
def null_motion_mu(S, jw, x, n, w):
    """μ(X N), N = I - J⁺J with J = S[jw, :3, :n] (Kraiem 2022 (3.24)-(3.25)), X = S[x, :3, :n];
    slots w … w+4: scratch.

    N is a symmetric projector, so (XN)(XN)ᵀ = X Xᵀ - (X Jᵀ)(J Jᵀ)⁻¹(X Jᵀ)ᵀ when J has full row
    rank (J Jᵀ well conditioned, cond(J) ≲ 1e7); otherwise (and n < 3) the pseudo-inverse. The
    subtraction keeps about half the digits: a value below √eps·‖X‖_F³ is round-off, reported 0.
    """
    G, Gi, XJ, XX = w, w + 1, w + 2, w + 3
    if n >= 3:
        mmt(S, jw, jw, G, 3, n, 3)
        tr = (S[G, 0, 0] + S[G, 1, 1] + S[G, 2, 2]) / 3.0
        if det3(S, G) > 1e-14 * tr ** 3:
            inv3(S, G, Gi)
            mmt(S, x, jw, XJ, 3, n, 3)
            mmt(S, x, x, XX, 3, n, 3)
            mm(S, XJ, Gi, G, 3, 3, 3)  # G is free again: (X Jᵀ)(J Jᵀ)⁻¹
            mmt(S, G, XJ, Gi, 3, 3, 3)  # … (X Jᵀ)ᵀ
            for i in range(3):
                for j in range(3):
                    S[Gi, i, j] = S[XX, i, j] - S[Gi, i, j]
            r = mu_of_gram(S, Gi, 3)
            floor = 1e-7 * (S[XX, 0, 0] + S[XX, 1, 1] + S[XX, 2, 2]) ** 1.5
            return 0.0 if r < floor else r
    J = S[jw, :3, :n].copy()
    S[G, :n, :n] = np.eye(n) - np.linalg.pinv(J) @ J  # N
    mm(S, x, G, XJ, 3, n, n)
    return manipulability(S, XJ, 3, n, Gi)


@njit(**JIT)
def zonotope_gauge(S, h, nv, g, nr):
    """max over the columns h of H = S[h, :3, :nv] of the gauge of h in the zonotope {G t, |t|∞ ≤ 1},
    G = S[g, :3, :nr] of rank 3: a 3-D zonotope's facets are parallel to pairs of generators, so
    the gauge is max_n |nᵀh| / Σ_i |nᵀ g_i| over n = g_i × g_j (pairs of parallel generators give
    n = 0 and are ignored)."""
    gmax = 0.0
    for i in range(3):
        for j in range(nr):
            gmax = max(gmax, abs(S[g, i, j]))
    tiny = 1e-12 * max(gmax, 1e-300)
    best = 0.0
    for i in range(nr):
        for j in range(i + 1, nr):
            n0 = S[g, 1, i] * S[g, 2, j] - S[g, 2, i] * S[g, 1, j]
            n1 = S[g, 2, i] * S[g, 0, j] - S[g, 0, i] * S[g, 2, j]
            n2 = S[g, 0, i] * S[g, 1, j] - S[g, 1, i] * S[g, 0, j]
            nn = math.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
            if not nn > tiny * gmax:
                continue
            n0, n1, n2 = n0 / nn, n1 / nn, n2 / nn
            supp = 0.0
            for l in range(nr):
                supp += abs(n0 * S[g, 0, l] + n1 * S[g, 1, l] + n2 * S[g, 2, l])
            if not supp > 0:
                continue
            for v in range(nv):
                best = max(best, abs(n0 * S[h, 0, v] + n1 * S[h, 1, v] + n2 * S[h, 2, v]) / supp)
    return best


@njit(**JIT)
def zonotope_gauge_stack(H, G):
    """:func:`zonotope_gauge` of each sample of stacks H (k × 3 × V), G (k × 3 × n)."""
    k, _, nv = H.shape
    nr = G.shape[2]
    S = np.empty((2, 3, max(nv, nr, 1)))
    out = np.empty(k)
    for s in range(k):
        S[0, :, :nv] = H[s]
        S[1, :, :nr] = G[s]
        out[s] = zonotope_gauge(S, 0, nv, 1, nr)
    return out


# ----------------------------------------------------------------------------- one sample, one block
# slots of the scratch S
RS, JD, SU, SUI, JLIN, JANG, JFIX, BM, XA, XL, DX, JTS, LIN, ANG, JW0, HM, HI, JDIA, JFS, GZ, HV, VERT, W = range(23)
NSLOT = W + 5


@njit(**JIT)
def _sample(M, J, arm, act, task6, what, q_max, omega_max, tau_max, nvert, out, A, Jst, S, c, d):
    """Every index of one sample (see :func:`block_indices`); A (3 × n) and Jst (6 × n) are filled.
    S: the scratch slots (the speed-box vertices in S[VERT]); c, d: 3-vectors of scratch."""
    nm, n = arm.shape[0], act.shape[0]
    nr = n - nm
    t = 6 if task6 else 3
    # EE frame → R_sat: the base-angular columns of the LOCAL Jacobian are R_eeᵀ R_0.
    for i in range(3):
        for j in range(3):
            S[RS, i, j] = J[3 + j, 3 + i]  # R_sat←ee
    for j in range(nm):
        for i in range(3):
            a = 0.0
            b = 0.0
            for l in range(3):
                a += S[RS, i, l] * J[l, arm[j]]
                b += S[RS, i, l] * J[3 + l, arm[j]]
            S[JLIN, i, j] = a
            S[JANG, i, j] = b
            S[JFIX, i, j] = a
            S[JFIX, 3 + i, j] = b  # rows 3..5 used by the "pose" task only
    # linear rows on the base angular columns: -[d]×, so the EE origin d in R_sat
    for i in range(3):
        for j in range(3):
            s = 0.0
            for l in range(3):
                s += S[RS, i, l] * J[l, 3 + j]
            S[JD, i, j] = s
    d[0], d[1], d[2] = S[JD, 1, 2], S[JD, 2, 0], S[JD, 0, 1]
    out[0], out[1], out[2] = d[0], d[1], d[2]
    out[3] = math.atan2(S[RS, 2, 1], S[RS, 2, 2])
    out[4] = math.asin(min(max(-S[RS, 2, 0], -1.0), 1.0))
    out[5] = math.atan2(S[RS, 1, 0], S[RS, 0, 0])
    out[6] = manipulability(S, JFIX, t, nm, W)
    out[7] = cond_of_gram(S, W, gram(S, JFIX, t, nm, W))
    if not what & FREE:
        return
    # Base block of M = [[m I, -m[c]×], [m[c]×, I_O]] (R_sat, base-link origin O, CoM c).
    m = M[0, 0]
    c[0], c[1], c[2] = M[5, 1] / m, M[3, 2] / m, M[4, 0] / m
    for i in range(6):
        for j in range(n):
            S[BM, i, j] = M[i, act[j]]  # momentum [p; h_O] per actuator rate
    cross_cols(S, c, BM, DX, n)
    for i in range(3):
        for j in range(n):
            A[i, j] = S[BM, 3 + i, j] - S[DX, i, j]  # h_G = h_O - c × p: arm columns, then wheels
    # Zero momentum, seed (3.5): ω_b = -S_U⁻¹ A, S_U = I_O + m[c]×[c]× (locked inertia about the CoM,
    # the Schur complement of (3.7)); v_b = -(p/m + c × S_U⁻¹ A).
    cc = c[0] * c[0] + c[1] * c[1] + c[2] * c[2]
    for i in range(3):
        for j in range(3):
            S[SU, i, j] = M[3 + i, 3 + j] + m * (c[i] * c[j] - (cc if i == j else 0.0))
    inv3(S, SU, SUI)
    for i in range(3):  # -ω_b per actuator rate
        for j in range(n):
            S[XA, i, j] = S[SUI, i, 0] * A[0, j] + S[SUI, i, 1] * A[1, j] + S[SUI, i, 2] * A[2, j]
    cross_cols(S, c, XA, XL, n)
    for i in range(3):
        for j in range(n):
            S[XL, i, j] += S[BM, i, j] / m  # -v_b per actuator rate
    # J* (3.8): [J_m; 0] plus the base-velocity map (EE velocity v_b + ω_b × d, EE rate ω_b).
    cross_cols(S, d, XA, DX, n)
    for i in range(3):
        for j in range(n):
            Jst[i, j] = S[DX, i, j] - S[XL, i, j]
            Jst[3 + i, j] = -S[XA, i, j]
        for j in range(nm):
            Jst[i, j] += S[JLIN, i, j]
            Jst[3 + i, j] += S[JANG, i, j]
    for i in range(t):
        for j in range(nm):
            S[JTS, i, j] = Jst[i, j]  # J*_mEE on the task rows
    if what & MANIP:
        out[8] = manipulability(S, JTS, t, nm, W)
        out[9] = cond_of_gram(S, W, gram(S, JTS, t, nm, W))
    if what & DYN:
        # H*_m = M_mm - M_mb M_bb⁻¹ M_bm (base free, wheels locked); J◇ = J* H*⁻¹ diag(τ_max)
        for i in range(nm):
            for j in range(nm):
                s = M[arm[i], arm[j]]
                for l in range(3):
                    s -= M[arm[i], l] * S[XL, l, j] + M[arm[i], 3 + l] * S[XA, l, j]
                S[HM, i, j] = s
        if nm == 3:
            inv3(S, HM, HI)
        else:
            S[HI, :nm, :nm] = np.linalg.inv(S[HM, :nm, :nm].copy())
        mm(S, JTS, HI, JDIA, t, nm, nm)
        for j in range(nm):
            for i in range(t):
                S[JDIA, i, j] *= tau_max[j]
        out[10] = manipulability(S, JDIA, t, nm, W)
    if what & BASE:
        fm = 0.0
        fr = 0.0
        for i in range(3):
            for j in range(nm):
                fm += A[i, j] * (A[i, j] * q_max[j] ** 2)  # ‖S_U J^ω0_m0 Q_max‖²_F
            for j in range(nr):
                fr += A[i, nm + j] * (A[i, nm + j] * omega_max[j] ** 2)
        tot = math.sqrt(fm + fr)
        out[11] = math.sqrt(fm) / tot
        out[12] = math.sqrt(fr) / tot
    if what & NULL:
        for j in range(n):
            sc = q_max[j] if j < nm else omega_max[j - nm]
            for i in range(3):
                S[LIN, i, j] = Jst[i, j] * sc  # J^scal_rEE (3.23)
                S[ANG, i, j] = Jst[3 + i, j] * sc  # J^scal_ωEE
                S[JW0, i, j] = -S[XA, i, j] * sc  # J^scal_ω0 (3.17a)
        out[13] = manipulability(S, LIN, 3, n, W)
        out[14] = null_motion_mu(S, JW0, LIN, n, W)
        out[15] = null_motion_mu(S, JW0, ANG, n, W)
        for i in range(3):
            for j in range(nm):
                S[JFS, i, j] = S[JLIN, i, j] * q_max[j]
        out[16] = manipulability(S, JFS, 3, nm, W)
    if what & MOMENTUM:
        for i in range(3):  # arm momentum at the speed-box vertices
            for j in range(nm):
                S[GZ, i, j] = A[i, j]
        mm(S, GZ, VERT, HV, 3, nm, nvert)
        hmax = 0.0
        for v in range(nvert):
            hmax = max(hmax, S[HV, 0, v] ** 2 + S[HV, 1, v] ** 2 + S[HV, 2, v] ** 2)
        out[17] = math.sqrt(hmax)
        if what & ZONOTOPE:
            for i in range(3):
                for j in range(nr):
                    S[GZ, i, j] = A[i, nm + j] * omega_max[j]
            out[18] = zonotope_gauge(S, HV, nvert, GZ, nr)


@njit(**JIT)
def block_indices(Ms, Js, arm, act, task6, what, q_max, omega_max, tau_max, vertices, out, A, Jst):
    """Indices of a block of samples from their mass matrices Ms (k × nv × nv) and LOCAL EE Jacobians
    Js (k × 6 × nv): ``out`` (k × len(OUT), columns :data:`OUT`), the centroidal momentum columns
    ``A`` (k × 3 × n, h_G per actuator rate, arm then wheels: ``act`` = their v indices) and the
    generalized Jacobians ``Jst`` (k × 6 × n, [J*_mEE J*_rEE], EE twist [v; ω] in R_sat).

    ``what``: bits FREE (the free-floating part: A, Jst), MANIP, DYN, BASE, NULL, MOMENTUM, ZONOTOPE
    (h_ratio for wheels spanning 3-D); ``task6``: the singularity test's task is the full twist
    (else the EE linear velocity); ``vertices``: the arm speed box's vertices (nm × V). Columns not
    asked for are left as they are. Releases the GIL: callers may run parts of a block on threads
    (a sample's values do not depend on the part it falls in)."""
    nm, nvert = vertices.shape
    S = np.empty((NSLOT, max(6, act.shape[0], Ms.shape[1], nvert), max(6, act.shape[0], Ms.shape[1], nvert)))
    S[VERT, :nm, :nvert] = vertices
    c = np.empty(3)
    d = np.empty(3)
    for s in range(Ms.shape[0]):
        _sample(Ms[s], Js[s], arm, act, task6, what, q_max, omega_max, tau_max, nvert, out[s], A[s], Jst[s], S, c, d)
