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

import numpy as np

from sms_cli.model.reduced import ReducedIndex, rest_matrices
from sms_cli.synthesis.lmi import ErrorModel

__all__ = ["ReducedIndex", "error_model_at_rest", "model_index", "flexible_stiffness", "error_model"]


def error_model_at_rest(M: np.ndarray, K_f: np.ndarray, C_f: np.ndarray, ix: ReducedIndex,
                        label: str = "") -> ErrorModel:
    """The Kraiem 2022 reduced matrices at rest from the full mass matrix M (n_x×n_x) and the
    flexible stiffness K_f and damping C_f (n_f×n_f) (``sms_cli.model.reduced.rest_matrices``), as the
    LMI's ErrorModel: A_e, C_e, B_ε, M◇, D◇_x."""
    r = rest_matrices(M, K_f, C_f, ix)
    n_q = ix.actuators.size
    return ErrorModel(A_e=r.A_e, C_e=r.C_e, B_eps=r.B_eps, M=r.M_dia, D_x=r.D_x, D_sym=np.zeros((n_q, n_q)), label=label)


def state_labels(n_f_names: list[str]) -> list[str]:
    """Names of x = [f; ω0; ḟ]."""
    return ([f"{n}" for n in n_f_names] + ["w0_x", "w0_y", "w0_z"] + [f"{n}_rate" for n in n_f_names])


# ---------------------------------------------------------------------------------------
# SystemModel side


def model_index(sm) -> tuple[ReducedIndex, list[str], list[str]]:
    """Index sets of a SystemModel, the actuator names (wheels, then arm) and flexible names (``sm.reduced``)."""
    red = sm.reduced
    return red.ix, list(red.actuator_names), list(red.flexible_names)


def flexible_stiffness(sm) -> tuple[np.ndarray, np.ndarray]:
    """K_f, C_f of [passive joints; modes] (N m/rad or N/m; modal: Ω², 2ζΩ) (``sm.reduced``)."""
    return sm.reduced.K_f, sm.reduced.C_f


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
    red = sm.reduced
    return error_model_at_rest(sm.mass_matrix(q), red.K_f, red.C_f, red.ix, label)
