"""Reduced actuator dynamics of Kraiem 2022 §3.3, linearised at rest, as LMI ``ErrorModel``s.

Coordinates (SystemModel, Pinocchio velocities): base linear (3), base angular ω0 (3, base
frame), actuators q (wheels then arm joints, v-index order), flexible coordinates f (passive
spring joints, then modal coordinates η). At rest (all velocities zero, the thesis's
equilibrium points) the convective terms vanish and the equations are

    M [v̇_lin; ω̇0; q̈; f̈] + [0; 0; 0; K_f f + C_f ḟ] = [0; 0; τ; 0].

1. The base translation is cyclic (free floating, zero gravity): eliminating it at constant
   linear momentum replaces M by its Schur complement on the remaining coordinates (Routh
   reduction; exact for the kinetic energy whatever the base-velocity convention). This also
   removes ṙ_S0 from the observer state: in Kraiem 2022 (3.30) it is an unobservable integrator of
   A_e at rest, which no observer gain can move (the LMI would be infeasible).
2. With b = [ω0; f]: observer model (3.28)–(3.30), x = [f; ω0; ḟ], y = ω0 (C_e = [0 I 0]):
   M* = M_bb − M_bq M_qq⁻¹ M_qb,  [ω̇0; f̈] = −M*⁻¹ [0; K_f f + C_f ḟ] (+ input terms).
3. Actuator dynamics (3.33)–(3.35): M◇ = M_qq − M_qb M_bb⁻¹ M_bq,
   D◇_x x = −M_qb M_bb⁻¹ [0; K_f f + C_f ḟ],  B_ε = M◇⁻¹ D◇_x.

Units: SI (rad, m, sqrt(kg) m for η). Frames: ω0 in the base frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sms_cli.synthesis.lmi import ErrorModel


@dataclass
class ReducedIndex:
    """Index sets into the augmented velocity x = [v; η̇] (size n_x)."""

    base_linear: np.ndarray
    base_angular: np.ndarray
    actuators: np.ndarray
    flexible: np.ndarray


def error_model_at_rest(M: np.ndarray, K_f: np.ndarray, C_f: np.ndarray, ix: ReducedIndex,
                        label: str = "") -> ErrorModel:
    """The Kraiem 2022 reduced matrices at rest from the full mass matrix M (n_x×n_x) and the
    flexible stiffness K_f and damping C_f (n_f×n_f). Returns A_e, C_e, B_ε, M◇, D◇_x."""
    keep = np.concatenate([ix.base_angular, ix.actuators, ix.flexible])
    lin = ix.base_linear
    Mk = M[np.ix_(keep, keep)]
    if len(lin):
        Mkl = M[np.ix_(keep, lin)]
        Mk = Mk - Mkl @ np.linalg.solve(M[np.ix_(lin, lin)], Mkl.T)
    n_w, n_q, n_f = len(ix.base_angular), len(ix.actuators), len(ix.flexible)
    b = np.concatenate([np.arange(n_w), n_w + n_q + np.arange(n_f)])  # [ω0; f] inside Mk
    a = n_w + np.arange(n_q)
    Mbb, Mbq, Mqq = Mk[np.ix_(b, b)], Mk[np.ix_(b, a)], Mk[np.ix_(a, a)]
    # generalized force on b per unit of x = [f; ω0; ḟ]: F_b = S x with S = [[0, 0, 0], [K_f, 0, C_f]]
    n_e = 2 * n_f + n_w
    S = np.zeros((n_w + n_f, n_e))
    S[n_w:, :n_f] = K_f
    S[n_w:, n_f + n_w:] = C_f
    Mstar = Mbb - Mbq @ np.linalg.solve(Mqq, Mbq.T)
    A = np.zeros((n_e, n_e))
    A[:n_f, n_f + n_w:] = np.eye(n_f)
    A[n_f:, :] = -np.linalg.solve(Mstar, S)
    C = np.zeros((n_w, n_e))
    C[:, n_f:n_f + n_w] = np.eye(n_w)
    Mdia = Mqq - Mbq.T @ np.linalg.solve(Mbb, Mbq)
    Dx = -Mbq.T @ np.linalg.solve(Mbb, S)
    B = np.linalg.solve(Mdia, Dx)
    Mdia = (Mdia + Mdia.T) / 2
    return ErrorModel(A_e=A, C_e=C, B_eps=B, M=Mdia, D_x=Dx, D_sym=np.zeros((n_q, n_q)), label=label)


def state_labels(n_f_names: list[str]) -> list[str]:
    """Names of x = [f; ω0; ḟ]."""
    return ([f"{n}" for n in n_f_names] + ["w0_x", "w0_y", "w0_z"] + [f"{n}_rate" for n in n_f_names])


# ---------------------------------------------------------------------------------------
# SystemModel side


def model_index(sm) -> tuple[ReducedIndex, list[str], list[str]]:
    """Index sets of a SystemModel, the actuator names (wheels, then arm) and flexible names."""
    act = np.concatenate([np.asarray(sm.idx.wheels, dtype=int), np.asarray(sm.idx.arm, dtype=int)])
    flex = np.concatenate([np.asarray(sm.idx.passive, dtype=int), np.asarray(sm.idx.modes, dtype=int)])
    names = [w.name for w in sm.wheels] + [j.name for j in sm.arm]
    fnames = [s.joint for s in sm.springs]
    for ap in sm.appendages:
        fnames += [f"{ap.name}_mode{k + 1}" for k in range(len(ap.omega))]
    ix = ReducedIndex(np.asarray(sm.idx.base_linear, dtype=int), np.asarray(sm.idx.base_angular, dtype=int),
                      act, flex)
    return ix, names, fnames


def flexible_stiffness(sm) -> tuple[np.ndarray, np.ndarray]:
    """K_f, C_f of [passive joints; modes] (N m/rad or N/m; modal: Ω², 2ζΩ)."""
    ks = [s.stiffness for s in sm.springs]
    cs = [s.damping for s in sm.springs]
    for ap in sm.appendages:
        om, ze = np.asarray(ap.omega, dtype=float), np.asarray(ap.zeta, dtype=float)
        ks += list(om**2)
        cs += list(2 * ze * om)
    return np.diag(np.asarray(ks, dtype=float)), np.diag(np.asarray(cs, dtype=float))


def configuration(sm, q_base: np.ndarray, joints: dict[str, float]) -> np.ndarray:
    """q with the named arm/passive joints set (positions in rad or m)."""
    q = np.array(q_base, dtype=float).copy()
    by_name = {j.name: j.q_index for j in sm.arm}
    by_name.update({s.joint: s.q_index for s in sm.springs})
    for name, val in joints.items():
        if name not in by_name:
            raise KeyError(name)
        q[by_name[name]] = val
    return q


def sample_configurations(sm, q_nom: np.ndarray, n: int, spread: float, seed: int) -> list[np.ndarray]:
    """n configurations with each arm joint uniform in [q_i − spread, q_i + spread] ∩ limits."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        q = q_nom.copy()
        for j in sm.arm:
            lo = max(q_nom[j.q_index] - spread, j.lower if np.isfinite(j.lower) else -np.inf)
            hi = min(q_nom[j.q_index] + spread, j.upper if np.isfinite(j.upper) else np.inf)
            if hi < lo:
                lo = hi = q_nom[j.q_index]
            q[j.q_index] = rng.uniform(lo, hi)
        out.append(q)
    return out


def error_model(sm, q: np.ndarray, label: str = "") -> ErrorModel:
    """The reduced linearisation of a SystemModel at configuration q, at rest."""
    ix, _, _ = model_index(sm)
    K_f, C_f = flexible_stiffness(sm)
    return error_model_at_rest(sm.mass_matrix(q), K_f, C_f, ix, label)
