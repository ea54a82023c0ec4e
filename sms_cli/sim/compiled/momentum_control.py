"""The momentum laws of Vicariotto 2023 (``momentum_laws``) in the compiled loop: the control of one tick
(the law, then the wheels' torque limit) and the quantities the Python loop records for them (the locked
velocity μ per tick, W and its terms after every plant step). Same sequence as
``sms_cli.sim.engine.Simulation._control`` / ``_trace`` / ``_lyapunov`` for a law with ``actuate``.

``model`` is the tuple of the kernels' model arguments (wheels, mass, com_base, Tv, I, G, J, Λ, M_θ;
``sms_cli.sim.laws.momentum._MomentumLaw.model_args``), constant while the mass is fixed.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from sms_cli.sim.compiled import JIT
from sms_cli.sim.compiled.dynamics import cholesky_solve_columns, joint_transforms, mass_matrix
from sms_cli.sim.compiled.momentum_laws import T_W, momentum_law, momentum_lyapunov


@njit(**JIT)
def momentum_control(code, q, v, ref, model, par, mem, max_torque, tau_w, wrench):
    """The law of ``code`` on the state (q, v) for the reference ``ref`` (xyzw): wheel motor torques (N m) into
    ``tau_w``, clipped to ±max_torque (``WheelArray.clip_torque``), and the base wrench ``[f; n]`` (base frame,
    about the base origin, N and N m) into ``wrench``; updates ``mem``. Returns whether a wheel saturated."""
    wheels, mass, com_base, Tv, I, G, J, Lam, M_theta = model
    momentum_law(code, q, v, ref, wheels, mass, com_base, Tv, I, G, J, Lam, M_theta, par, mem, tau_w, wrench)
    sat = False
    for i in range(tau_w.shape[0]):
        lim = max_torque[i]
        if abs(tau_w[i]) > lim * (1 + 1e-12):
            sat = True
        tau_w[i] = min(max(tau_w[i], -lim), lim)
    return sat


@njit(**JIT)
def locked_velocity(v, model, mu):
    """μ = ω + Λθ̇ (rad/s, base frame; Vicariotto 2023 (4.8)) into ``mu``: the law's ``locked_velocity``."""
    wheels, Lam = model[0], model[7]
    for i in range(3):
        s = 0.0
        for j in range(wheels.shape[0]):
            s += Lam[i, j] * v[wheels[j]]
        mu[i] = v[3 + i] + s


@njit(**JIT)
def lyapunov_terms(code, q, v, ref, model, par, mem, out):
    """W and its terms (layout ``momentum_laws.T_*``) of the law of ``code`` on (q, v) into ``out``; returns W."""
    wheels, mass, com_base, Tv, I, G, J, Lam, M_theta = model
    momentum_lyapunov(code, q, v, ref, wheels, mass, com_base, Tv, I, G, J, Lam, M_theta, par, mem, out)
    return out[T_W]


@njit(**JIT)
def locked_reduction_into(M, A, I, Lam_s, L, col):
    """The translation, then the rotation, reduced out of the base rows of a mass matrix M (n × n, base
    coordinates first: rigid nv, or augmented with the modes; ``sms_cli.dynamics.locked._reduce``), into
    A = M_vv⁻¹[M_vω, M_vs] (3, n − 3), I (3, 3) the symmetrised angular block of red = M_ω· − M_ωv A (kg m², base
    frame, about the CoM) and Λ_s = I⁻¹ red_s (3, n − 6). No allocation (M_vv and I by Cholesky; L (3, 3) and col
    (3,) scratch)."""
    n = M.shape[0]
    for i in range(3):
        for j in range(n - 3):
            A[i, j] = M[i, 3 + j]
    cholesky_solve_columns(M, 3, A, L, col)  # M_vv: M's leading 3×3 block
    for i in range(3):
        for j in range(n - 3):
            r = M[3 + i, 3 + j] - (M[3 + i, 0] * A[0, j] + M[3 + i, 1] * A[1, j] + M[3 + i, 2] * A[2, j])
            if j < 3:
                I[i, j] = r
            else:
                Lam_s[i, j - 3] = r
    for i in range(3):
        for j in range(i):
            x = 0.5 * (I[i, j] + I[j, i])
            I[i, j] = x
            I[j, i] = x
    cholesky_solve_columns(I, 3, Lam_s, L, col)


@njit(**JIT)
def locked_reduction(M):
    """(A, I, Λ_s) of ``locked_reduction_into``, allocated."""
    n = M.shape[0]
    A, I, Lam_s = np.empty((3, n - 3)), np.empty((3, 3)), np.empty((3, n - 6))
    locked_reduction_into(M, A, I, Lam_s, np.empty((3, 3)), np.empty(3))
    return A, I, Lam_s


@njit(**JIT)
def _locked_velocity(M, x, A, I, Lam_s, L, col, mu):
    """μ = ω + Λ_s ṡ (rad/s, base frame) into mu (3,) for the mass matrix M (nx × nx) and the velocity x (nx: v, then
    the modal rates; ṡ = x[6:]), with the scratch A, I, Λ_s, L, col of ``locked_reduction_into``."""
    locked_reduction_into(M, A, I, Lam_s, L, col)
    for i in range(3):
        acc = 0.0
        for j in range(Lam_s.shape[1]):
            acc += Lam_s[i, j] * x[6 + j]
        mu[i] = x[3 + i] + acc


@njit(**JIT)
def locked_velocities_of(Ms, xs, out):
    """μ (n, 3) into out for the stacks of mass matrices Ms (n, nx, nx) and velocities xs (n, nx) (``_locked_velocity``,
    every shape coordinate: wheels, arm, modal rates; ``sms_cli.dynamics.locked.locked_velocity``)."""
    nx = Ms.shape[1]
    A, I, Lam_s, L, col = np.empty((3, nx - 3)), np.empty((3, 3)), np.empty((3, nx - 6)), np.empty((3, 3)), np.empty(3)
    for s in range(Ms.shape[0]):
        _locked_velocity(Ms[s], xs[s], A, I, Lam_s, L, col, out[s])


@njit(**JIT)
def sample_locked_velocities(parent, kind, axis, place_R, place_p, inertia, armature, idx_q, idx_v, qs, vs, out):
    """μ (rad/s, base frame) of rigid states (rows of qs, vs: no modes) into out (n, 3), each from the rigid mass
    matrix at its q (``dynamics.mass_matrix``): ``sms_cli.dynamics.locked.locked_velocities`` of the compiled tree."""
    n, nv = parent.shape[0], vs.shape[1]
    R_rel, p_rel = np.empty((n, 3, 3)), np.empty((n, 3))
    M = np.empty((nv, nv))
    A, I, Lam_s, L, col = np.empty((3, nv - 3)), np.empty((3, 3)), np.empty((3, nv - 6)), np.empty((3, 3)), np.empty(3)
    for s in range(qs.shape[0]):
        joint_transforms(kind, axis, place_R, place_p, idx_q, qs[s], R_rel, p_rel)
        mass_matrix(parent, kind, axis, inertia, armature, idx_v, R_rel, p_rel, M)
        _locked_velocity(M, vs[s], A, I, Lam_s, L, col, out[s])


@njit(**JIT)
def locked_model(M, wheels):
    """The model tuple of the rigid mass matrix M (nv × nv, ``mass_matrix``): ``sms_cli.dynamics.locked.locked_shape``
    and ``_MomentumLaw._model_args`` for a base with wheels only, for a mass that changes (propellant spent):
    A = M_vv⁻¹[M_vω, M_vs] (= Tv), I the translation-reduced angular block (symmetrised), Λ_s = I⁻¹(reduced
    coupling), M_θ = M_ss − M_vsᵀA_s − (IΛ_s)ᵀΛ_s (symmetrised), J, G J = IΛ_s on the wheel columns."""
    nv = M.shape[0]
    ns = nv - 6
    n = wheels.shape[0]
    A, I, Lam_s = locked_reduction(M)
    C_s = I @ Lam_s
    Mt = np.ascontiguousarray(M[6:, 6:]) - np.ascontiguousarray(M[0:3, 6:]).T @ np.ascontiguousarray(A[:, 3:]) \
        - np.ascontiguousarray(C_s.T) @ Lam_s
    M_theta = 0.5 * (Mt + Mt.T)
    J, G, Lam = np.empty(n), np.empty((3, n)), np.empty((3, n))
    for k in range(n):
        c = wheels[k] - 6
        J[k] = M[wheels[k], wheels[k]]
        for i in range(3):
            G[i, k] = C_s[i, c] / J[k]
            Lam[i, k] = Lam_s[i, c]
    com = np.empty(3)
    com[0], com[1], com[2] = -A[2, 1], -A[0, 2], -A[1, 0]
    return wheels, M[0, 0], com, np.ascontiguousarray(A), I, G, J, Lam, np.ascontiguousarray(M_theta[:ns, :ns])
