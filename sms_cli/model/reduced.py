"""The reduced form of a SystemModel for Kraiem 2022 §3.3 (NDI synthesis and law): index sets of the
augmented velocity x = [v; η̇], actuator and flexible names, flexible stiffness and damping, and the
matrices linearised at rest (``at_rest``). Built once per SystemModel (``SystemModel.reduced``) and
used by both the synthesis (``sms_cli.synthesis.reduced``) and the law (``sms_cli.sim.laws.ndi``).

Coordinates: base linear (3), base angular ω0 (3, base frame), actuators (wheels then arm joints,
v-index order), flexible f (passive spring joints, then modal coordinates η). Units SI (rad, m,
sqrt(kg) m for η).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class ReducedIndex:
    """Index sets into the augmented velocity x = [v; η̇] (size n_x), int64."""

    base_linear: np.ndarray
    base_angular: np.ndarray
    actuators: np.ndarray
    flexible: np.ndarray

    def __post_init__(self) -> None:
        for name in ("base_linear", "base_angular", "actuators", "flexible"):
            setattr(self, name, np.ascontiguousarray(getattr(self, name), dtype=np.int64))


@dataclass
class RestMatrices:
    """The reduced matrices at rest: A_e (n_e×n_e), C_e (3×n_e) of x_e = [f; ω0; ḟ]; the observer's input
    matrix B_τ (n_e×n_q); M◇ (n_q×n_q), D◇_x (n_q×n_e), B_ε = M◇⁻¹ D◇_x."""

    A_e: np.ndarray
    C_e: np.ndarray
    B_tau: np.ndarray
    M_dia: np.ndarray
    D_x: np.ndarray
    B_eps: np.ndarray


def rest_matrices(M: np.ndarray, K_f: np.ndarray, C_f: np.ndarray, ix: ReducedIndex) -> RestMatrices:
    """The reduced matrices at rest from the augmented mass matrix M (nx×nx) and the flexible K_f, C_f
    (``sms_cli.sim.compiled.ndi_law.reduced_at_rest``, the one implementation)."""
    from sms_cli.sim.compiled.ndi_law import reduced_at_rest

    n_w, n_q, n_f = ix.base_angular.size, ix.actuators.size, ix.flexible.size
    n_e = 2 * n_f + n_w
    A, B_tau, Md, Dx, B = np.empty((n_e, n_e)), np.empty((n_e, n_q)), np.empty((n_q, n_q)), np.empty((n_q, n_e)), np.empty((n_q, n_e))
    f = lambda x: np.ascontiguousarray(x, dtype=float)  # noqa: E731
    reduced_at_rest(f(M), ix.base_linear, ix.base_angular, ix.actuators, ix.flexible, f(K_f), f(C_f), A, B_tau, Md, Dx, B)
    C = np.zeros((n_w, n_e))
    C[:, n_f:n_f + n_w] = np.eye(n_w)
    return RestMatrices(A, C, B_tau, Md, Dx, B)


@dataclass
class ReducedModel:
    """A SystemModel's reduced form (see the module docstring)."""

    ix: ReducedIndex
    actuator_names: list[str]
    flexible_names: list[str]
    K_f: np.ndarray  # (n_f×n_f) N m/rad, N/m; modal: Ω² (1/s²)
    C_f: np.ndarray  # (n_f×n_f) N m s/rad, N s/m; modal: 2ζΩ (1/s)

    def at_rest(self, M: np.ndarray) -> RestMatrices:
        """The reduced matrices at rest at the configuration whose augmented mass matrix is M."""
        return rest_matrices(M, self.K_f, self.C_f, self.ix)


def reduced_model(sm) -> ReducedModel:
    """The reduced form of SystemModel ``sm`` (use ``sm.reduced``, built once)."""
    act = np.concatenate([np.asarray(sm.idx.wheels, dtype=int), np.asarray(sm.idx.arm, dtype=int)])
    flex = np.concatenate([np.asarray(sm.idx.passive, dtype=int), np.asarray(sm.idx.modes, dtype=int)])
    names = [w.name for w in sm.wheels] + [j.name for j in sm.arm]
    fnames = [s.joint for s in sm.springs]
    ks = [s.stiffness for s in sm.springs]
    cs = [s.damping for s in sm.springs]
    for ap in sm.appendages:
        fnames += [f"{ap.name}_mode{k + 1}" for k in range(len(ap.omega))]
        om, ze = np.asarray(ap.omega, dtype=float), np.asarray(ap.zeta, dtype=float)
        ks += list(om**2)
        cs += list(2 * ze * om)
    ix = ReducedIndex(np.asarray(sm.idx.base_linear, dtype=int), np.asarray(sm.idx.base_angular, dtype=int), act, flex)
    return ReducedModel(ix, names, fnames, np.diag(np.asarray(ks, dtype=float)), np.diag(np.asarray(cs, dtype=float)))
