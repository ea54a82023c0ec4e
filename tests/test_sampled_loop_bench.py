"""benches/sampled_loop.py, behind the README's account of the LMI gains' divergence on pulsar_full: its one-tick
transition matrix of [X; x̂] against an independent integration of the same loop (the plant's ODE by scipy's
solve_ivp with the torque held over the tick, the observer stepped as ``ndi_law.ndi_observe`` steps it)."""

from __future__ import annotations

import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
from scipy.integrate import solve_ivp

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benches"))

from sampled_loop import sampled_loop  # noqa: E402

from sms_cli.sim.compiled.ndi_law import observer_discretisation  # noqa: E402


def _rest(rng, n_q, n_f, scale):
    """RestMatrices-like random matrices: A_e of lightly damped modes and base rates, B_τ, M◇ (SPD), D◇_x."""
    n_e = 2 * n_f + 3
    A = np.zeros((n_e, n_e))
    A[:n_f, n_f + 3:] = np.eye(n_f)
    A[n_f:, :] = scale * rng.normal(size=(n_f + 3, n_e))
    A[n_f + 3:, :n_f] -= np.diag(rng.uniform(1.0, 9.0, n_f))
    C = np.zeros((3, n_e))
    C[:, n_f:n_f + 3] = np.eye(3)
    Q = rng.normal(size=(n_q, n_q))
    return SimpleNamespace(A_e=A, C_e=C, B_tau=np.vstack([np.zeros((n_f, n_q)), rng.normal(size=(n_f + 3, n_q))]),
                           M_dia=Q @ Q.T + n_q * np.eye(n_q), D_x=rng.normal(size=(n_q, n_e)))


def test_the_transition_matrix_is_one_tick_of_the_loop_as_flown():
    rng = np.random.default_rng(4)
    n_q, n_f, T = 3, 2, 0.1
    plant, law = _rest(rng, n_q, n_f, 0.3), _rest(rng, n_q, n_f, 0.3)  # the law's model differs from the plant's
    n_e = 2 * n_f + 3
    kp, kv, L = rng.uniform(0.1, 1.0, n_q), rng.uniform(0.5, 2.0, n_q), rng.normal(size=(n_e, 3))
    F = sampled_loop(plant, law, kp, kv, L, T)

    q, qd, x, xh = rng.normal(size=n_q), rng.normal(size=n_q), rng.normal(size=n_e), rng.normal(size=n_e)
    tau = law.M_dia @ (-kp * q - kv * qd) + law.D_x @ xh  # the law's command at the tick, held over it
    M_inv = np.linalg.inv(plant.M_dia)

    def plant_ode(_, s):
        qd_, x_ = s[n_q:2 * n_q], s[2 * n_q:]
        return np.concatenate([qd_, M_inv @ (tau - plant.D_x @ x_), plant.A_e @ x_ + plant.B_tau @ tau])

    X1 = solve_ivp(plant_ode, (0.0, T), np.concatenate([q, qd, x]), rtol=1e-12, atol=1e-13).y[:, -1]
    Phi, Gamma = np.empty((n_e, n_e)), np.empty((n_e, n_e))
    observer_discretisation(np.ascontiguousarray(law.A_e - L @ law.C_e), T, Phi, Gamma)
    xh1 = Phi @ xh + Gamma @ (law.B_tau @ tau + L @ (plant.C_e @ x))  # the gyro sampled at the tick
    want = np.concatenate([X1, xh1])
    got = F @ np.concatenate([q, qd, x, xh])
    assert np.abs(got - want).max() <= 1e-9 * np.abs(want).max()
