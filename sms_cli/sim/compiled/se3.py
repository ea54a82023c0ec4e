"""Compiled (numba) SE(3) logarithm and its Jacobian, Pinocchio's conventions (``pin.log3``, ``pin.log6``,
``pin.Jlog6``; tests/test_compiled_pair.py): a pose (R, p) maps frame coordinates to its parent's (m);
log6 = [v; ω] linear first (m, rad) with exp6(log6(M)) = M; Jlog6 (6×6) = d log6(M exp6(δ)) / dδ at δ = 0
(a body-frame perturbation δ = [δv; δω]).

The scalar functions of the rotation angle θ use their Taylor series for θ < 0.1 (Pinocchio switches at
θ ≈ 6e-6 and loses digits to cancellation in between); the results agree with Pinocchio's to its round-off.
"""

from __future__ import annotations

import math

from numba import njit

from sms_cli.sim.compiled import JIT

_SERIES = 0.1  # θ below which the angle functions use their series (truncation < 1e-16 there)
_NEAR_PI = 1e-2  # θ above π − this: the rotation vector from R's diagonal (Pinocchio's log3 branch)


@njit(**JIT)
def log3(R, w):
    """w (3) = the rotation vector of R (3×3), |w| = θ ∈ [0, π] (rad); returns θ."""
    a0, a1, a2 = R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]  # 2 sin θ · axis
    s = 0.5 * math.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
    c = 0.5 * (R[0, 0] + R[1, 1] + R[2, 2] - 1.0)
    theta = math.atan2(s, c)
    if theta >= math.pi - _NEAR_PI:  # sin θ ~ 0: |θ u_i| = θ √((R_ii − cos θ) / (1 − cos θ)) from the diagonal;
        ct = math.cos(theta)  # the sign of the largest component from a (+ at θ = π), the others' relative to it
        b = theta * theta / (1.0 - ct)  # from the symmetric part, R_ik + R_ki = 2 (1 − cos θ) u_i u_k
        k = 0
        if R[1, 1] > R[k, k]:
            k = 1
        if R[2, 2] > R[k, k]:
            k = 2
        ak = a0 if k == 0 else (a1 if k == 1 else a2)
        sk = -1.0 if ak < 0 else 1.0
        for i in range(3):
            x = (R[i, i] - ct) * b
            m = math.sqrt(x) if x > 0 else 0.0
            w[i] = sk * m if i == k else (sk if R[i, k] + R[k, i] >= 0 else -sk) * m
        return theta
    if theta < 1e-6:  # θ / (2 sin θ) (no cancellation above; 0/0 at θ = 0)
        f = 0.5 * (1.0 + theta * theta / 6.0)
    else:
        f = 0.5 * theta / math.sin(theta)
    w[0], w[1], w[2] = f * a0, f * a1, f * a2
    return theta


@njit(**JIT)
def _alpha_beta(theta):
    """(α, β, β'/θ) of the angle θ: α = (θ/2) cot(θ/2), β = (1 − α)/θ², β' = dβ/dθ; the SO(3) right Jacobian
    inverse is α I + ½[w]× + β w wᵀ and log6's linear part α p − ½ w × p + β (w·p) w."""
    t2 = theta * theta
    if theta < _SERIES:
        alpha = 1.0 - t2 * (1.0 / 12.0 + t2 * (1.0 / 720.0 + t2 * (1.0 / 30240.0 + t2 * (1.0 / 1209600.0))))
        beta = 1.0 / 12.0 + t2 * (1.0 / 720.0 + t2 * (1.0 / 30240.0 + t2 * (1.0 / 1209600.0 + t2 / 47900160.0)))
        bdot = 1.0 / 360.0 + t2 * (1.0 / 7560.0 + t2 * (1.0 / 201600.0 + t2 / 5987520.0))
        return alpha, beta, bdot
    h = 0.5 * theta
    sh = math.sin(h)
    alpha = h * math.cos(h) / sh
    beta = (1.0 - alpha) / t2
    # α' = ½ cot(θ/2) − (θ/4) / sin²(θ/2); β' = −α'/θ² − 2β/θ
    dalpha = 0.5 * math.cos(h) / sh - 0.25 * theta / (sh * sh)
    bdot = (-dalpha / theta - 2.0 * beta) / t2
    return alpha, beta, bdot


@njit(**JIT)
def log6(R, p, out):
    """out (6) = log6 of the pose (R, p): [v; ω] (m, rad), ω = log3(R), v = α p − ½ ω × p + β (ω·p) ω."""
    w = out[3:6]
    theta = log3(R, w)
    alpha, beta, _ = _alpha_beta(theta)
    wp = w[0] * p[0] + w[1] * p[1] + w[2] * p[2]
    out[0] = alpha * p[0] - 0.5 * (w[1] * p[2] - w[2] * p[1]) + beta * wp * w[0]
    out[1] = alpha * p[1] - 0.5 * (w[2] * p[0] - w[0] * p[2]) + beta * wp * w[1]
    out[2] = alpha * p[2] - 0.5 * (w[0] * p[1] - w[1] * p[0]) + beta * wp * w[2]


@njit(**JIT)
def jlog6(R, p, J, C):
    """J (6×6) = Jlog6 of the pose (R, p) (``pin.Jlog6``): [[A, C A], [0, A]] with A = α I + ½[ω]× + β ω ωᵀ the
    SO(3) block and C = (β'/θ (ω·p)) ω ωᵀ − (θ² β'/θ + 2β) p ωᵀ + β ω pᵀ + β (ω·p) I + ½[p]×; C is 3×3 scratch."""
    w0 = J[0, 0:3]  # the rotation vector, kept in a row of J's zero block until that block is cleared
    theta = log3(R, w0)
    x, y, z = w0[0], w0[1], w0[2]
    alpha, beta, bdot = _alpha_beta(theta)
    w = (x, y, z)
    for a in range(3):
        for b in range(3):
            J[3 + a, 3 + b] = beta * w[a] * w[b]
        J[3 + a, 3 + a] += alpha
    J[3, 4] -= 0.5 * z
    J[3, 5] += 0.5 * y
    J[4, 3] += 0.5 * z
    J[4, 5] -= 0.5 * x
    J[5, 3] -= 0.5 * y
    J[5, 4] += 0.5 * x
    wp = x * p[0] + y * p[1] + z * p[2]
    k = theta * theta * bdot + 2.0 * beta
    for a in range(3):
        for b in range(3):
            C[a, b] = (bdot * wp * w[a] - k * p[a]) * w[b] + beta * w[a] * p[b]
        C[a, a] += wp * beta
    C[0, 1] -= 0.5 * p[2]
    C[0, 2] += 0.5 * p[1]
    C[1, 0] += 0.5 * p[2]
    C[1, 2] -= 0.5 * p[0]
    C[2, 0] -= 0.5 * p[1]
    C[2, 1] += 0.5 * p[0]
    for a in range(3):
        for b in range(3):
            J[a, b] = J[3 + a, 3 + b]
            J[3 + a, b] = 0.0
            acc = 0.0
            for c in range(3):
                acc += C[a, c] * J[3 + c, 3 + b]
            J[a, 3 + b] = acc
