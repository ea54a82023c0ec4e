"""Gains of the NDI law designed from the law's own model when no LMI synthesis gives them (``simulation.ndi``:
``L: kalman``, ``ndo_bandwidth``): standard designs on the reduced model linearised at rest at the initial
configuration (``SystemModel.reduced.at_rest``), documented in the mission that uses them.

- ``kalman_gain``: the steady-state Kalman filter of x_e = [f; ω0; ḟ] from the gyro y = ω0 (Kraiem 2022 (3.31)'s
  observer structure, ẋ_e = A_e x_e + …, y = C_e x_e), L = P C_eᵀ V⁻¹ with P the stabilising solution of
  A_e P + P A_eᵀ − P C_eᵀ V⁻¹ C_e P + W = 0, W = w I (process), V = v I (gyro): A_e − L C_e is Hurwitz whenever
  (A_e, C_e) is detectable (every mode that the gyro does not see is damped).
- ``ndo_gain``: Q_d = β M◇, so that the disturbance observer's gain L_d = Q_d M◇⁻¹ (Kraiem 2022 (4.33)) is β I at
  the design configuration: each actuator's estimate converges at β (1/s).
"""

from __future__ import annotations

import numpy as np
import scipy.linalg

from sms_cli.model.system import SystemModel


def _rest(sm: SystemModel):
    return sm.reduced.at_rest(sm.mass_matrix(sm.q0))


def kalman_gain(sm: SystemModel, process: float, measurement: float) -> np.ndarray:
    """L (n_e × 3) of the steady-state Kalman filter of the module docstring, on ``sm`` at its initial configuration."""
    rest = _rest(sm)
    n_e = rest.A_e.shape[0]
    P = scipy.linalg.solve_continuous_are(rest.A_e.T, rest.C_e.T, process * np.eye(n_e), measurement * np.eye(3))
    return P @ rest.C_e.T / measurement


def ndo_gain(sm: SystemModel, bandwidth: float) -> np.ndarray:
    """Q_d = β M◇ (N m s per rad, actuators × actuators) at ``sm``'s initial configuration, β in 1/s."""
    M_dia = _rest(sm).M_dia
    return bandwidth * (M_dia + M_dia.T) / 2
