"""Linear modal quantities of the compiled system at a configuration."""

from __future__ import annotations

import numpy as np
import scipy.linalg

from sms_cli.model.system import SystemModel


def stiffness_matrix(sm: SystemModel) -> np.ndarray:
    """Linear stiffness K (nx×nx) of springs and modes about their rest state."""
    K = np.zeros((sm.nx, sm.nx))
    for s in sm.springs:
        K[s.v_index, s.v_index] = s.stiffness
    if sm.n_modes:
        K[sm.idx.modes, sm.idx.modes] = np.concatenate([a.omega for a in sm.appendages]) ** 2
    return K


def coupled_frequencies(sm: SystemModel, q: np.ndarray | None = None) -> np.ndarray:
    """Undamped free-free natural frequencies (rad/s, ascending) of the elastic coordinates:
    the positive roots of det(K − ω² M(q)) = 0 (rigid-body and joint zeros dropped)."""
    q = sm.q0 if q is None else q
    K = stiffness_matrix(sm)
    n_elastic = int(np.count_nonzero(np.diag(K)))
    if n_elastic == 0:
        return np.zeros(0)
    w2 = scipy.linalg.eigh(K, sm.mass_matrix(q), eigvals_only=True)
    return np.sqrt(np.sort(np.clip(w2, 0.0, None))[-n_elastic:])
