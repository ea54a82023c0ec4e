"""Kraiem 2022 ch. 4's nonlinear disturbance observer (4.12) in the NDI law (``ndi.disturbance_observer``):
the discrete observer against its closed form, both loops equal with it on, and a constant disturbance
cancelled (the attitude error it leaves under the NDI alone removed)."""

from __future__ import annotations

import json

import numpy as np
import pytest
import scipy.linalg

from sms_cli.sim.compiled import ndi_law as K
from test_compiled_ndi import FLAGSHIP, ROOT, _gains, pulsar  # noqa: F401  (fixture)


def _index_sets(nx: int, n_f: int, na: int):
    lin, ang = np.arange(3), np.arange(3, 6)
    act = np.arange(6, 6 + na)
    flex = np.arange(6 + na, 6 + na + n_f)
    assert flex[-1] == nx - 1
    return lin, ang, act, flex


def test_the_discrete_observer_converges_as_its_closed_form():
    """Constant M, r, applied torques and disturbance τ_d: the actuators accelerate at q̈ = M◇⁻¹(τ + τ_d − n)
    (M◇, n from numpy's Schur complement here), and the estimate error e_k = τ̂_k − τ_d must be
    e^(−Q_d M◇⁻¹ kT) e_0 (scipy's expm) at every tick: the observer's fixed point is exactly τ_d."""
    rng = np.random.default_rng(4)
    na, n_f = 5, 4
    nx = 6 + na + n_f
    A = rng.normal(size=(nx, nx))
    M = A @ A.T + nx * np.eye(nx)
    r = rng.normal(size=nx)
    lin, ang, act, flex = _index_sets(nx, n_f, na)
    u = np.r_[lin, ang, flex]
    M_dia = M[np.ix_(act, act)] - M[np.ix_(act, u)] @ np.linalg.solve(M[np.ix_(u, u)], M[np.ix_(u, act)])
    n = r[act] - M[np.ix_(act, u)] @ np.linalg.solve(M[np.ix_(u, u)], r[u])
    Q_d = 0.8 * M_dia + 0.1 * np.diag(rng.uniform(1, 2, na))
    T = 0.1
    tau, tau_d = rng.normal(size=na), rng.normal(size=na)
    qdd = np.linalg.solve(M_dia, tau + tau_d - n)
    Phi = scipy.linalg.expm(-Q_d @ np.linalg.inv(M_dia) * T)
    flags = np.zeros(K.N_FLAGS, dtype=np.int64)
    nPhi, nH, ng, tau_hat = np.zeros((na, na)), np.zeros((na, na)), np.zeros(na), np.zeros(na)
    qd = rng.normal(size=na)
    e0 = tau_hat - tau_d
    worst = 0.0
    for k in range(1, 40):
        K.ndo_refresh(M_dia, n, qd.copy(), tau, Q_d, T, flags, nPhi, ng, nH)
        qd = qd + T * qdd
        K.ndo_estimate(qd.copy(), flags, nPhi, ng, nH, tau_hat)
        want = np.linalg.matrix_power(Phi, k) @ e0
        worst = max(worst, np.abs((tau_hat - tau_d) - want).max())
    assert worst < 1e-12 * np.abs(e0).max()
    assert np.abs(tau_hat - tau_d).max() < 0.1 * np.abs(e0).max()  # and it did converge
    # no refresh, no update
    before = tau_hat.copy()
    K.ndo_estimate(qd, flags, nPhi, ng, nH, tau_hat)
    assert np.array_equal(tau_hat, before)


def _ndo_gains(sm, rate: float = 0.5) -> dict:
    """_gains plus Q_d = rate · M◇(q0): the observer's poles at −rate (1/s) at the initial configuration."""
    M_dia = sm.reduced.at_rest(sm.mass_matrix(sm.q0)).M_dia
    return dict(_gains(sm), disturbance_observer=True, Q_d=(rate * M_dia).tolist())


def _text(engine: str, gains: dict, phases: str, extra: str = "") -> str:
    return (f"extends: {ROOT / 'missions' / 'pulsar_simple.yaml'}\nname: ndo_{engine}\nsimulation:\n"
            f"  engine: {engine}\n  ndi: {json.dumps(dict(gains, attitude_gain=0.05))}\n{extra}  phases:\n{phases}")


def test_both_loops_equal_with_the_disturbance_observer(tmp_path, pulsar):  # noqa: F811
    from test_compiled_arm import _compare_missions_text

    py, _ = _compare_missions_text(tmp_path, lambda e: _text(e, _ndo_gains(pulsar), FLAGSHIP))
    assert py["overall"]["saturation_time_s"] == 0.0


HOLD = "    - {name: hold, kind: hold, duration: 120 s, attitude: [0, 0, 0]}\n"
# a constant torque on the base, and Coulomb friction in the wheel bearings: constant disturbances of the
# actuators' dynamics once the wheels spin one way
DISTURBANCES = ("  disturbances: [{kind: constant, frame: base, torque: [0, 0.02, 0]}]\n"
                "  wheel_friction: {coulomb: 0.005}\n")


def _hold(pulsar, gains):
    from sms_cli.mission.load import load_mission_text
    from sms_cli.sim.engine import Simulation
    from sms_cli.sim.stage import prepared_simulation

    loaded = load_mission_text(_text("python", gains, HOLD, DISTURBANCES), base_dir=ROOT / "missions", name="ndo.yaml")
    sm, spec, _ = prepared_simulation(loaded)
    sim = Simulation(sm, spec, None, False, mission_dir=ROOT / "missions")
    res = sim.run()
    assert res.status == "completed"
    return sm, sim, res


def test_constant_disturbances_are_estimated_and_their_joint_error_removed(pulsar):  # noqa: F811
    """A 120 s attitude hold under constant disturbances of the actuators' dynamics (the Python loop: the compiled
    NDI loop does not take disturbance wrenches; both loops call the same observer kernels, held equal above).

    - The wheel entries of the estimate τ̂_d must reach the disturbance of the wheels' reduced dynamics,
      computed here from Pinocchio's mass matrix: τ_d = f_a − M_au M_uu⁻¹ F_u with f_a the bearings'
      friction −c sign(ω) and F_u the base torque on the base coordinates (u: base and modes). The observer's
      fixed point is τ_d plus the law's model error at the estimated state, D◇_x ε_e (Kraiem 2022 (4.7)),
      which the wheels' rows see only through the base (I_s/I_base ~ 1e-5): bound 1e-4 of max |τ_d|.
    - The arm joints, held by the law's PD, are left by the NDI alone with the constant error that balances
      their disturbance (ε = (M◇ kp)⁻¹ τ_d); subtracting τ̂_d is an integral action: below 1 % of it."""
    sm, sim, res = _hold(pulsar, _ndo_gains(pulsar))
    ix = sm.reduced.ix
    M = sm.mass_matrix(sm.q0)  # the arm is held; the wheels' angles do not change M
    act = ix.actuators
    u = np.r_[ix.base_linear, ix.base_angular, ix.flexible]
    F = np.zeros(sm.nx)
    F[ix.base_angular] = [0, 0.02, 0]
    f_a = np.zeros(act.size)
    f_a[:4] = -0.005 * np.sign(res.trace["wheel_speed"][-1])
    tau_d = f_a - M[np.ix_(act, u)] @ np.linalg.solve(M[np.ix_(u, u)], F[u])
    assert np.abs(sim.ndi.tau_hat[:4] - tau_d[:4]).max() < 1e-4 * np.abs(tau_d).max(), (sim.ndi.tau_hat, tau_d)
    assert np.abs(tau_d[4:]).max() > 1e-4  # the base torque does load the arm joints
    _, _, plain = _hold(pulsar, _gains(pulsar))
    left = np.abs(plain.trace["joint_err"][-1]).max()
    assert left > 1e-6
    assert np.abs(res.trace["joint_err"][-1]).max() < 1e-2 * left
