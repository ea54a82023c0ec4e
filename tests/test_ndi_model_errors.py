"""The NDI law's own model with Kraiem 2022 §4.3's errors (sms_cli.model.model_errors) and the split of its command
into feedback, linearising and disturbance torques (ndi_law.torque_split): each checked against what it claims, on
the flagship's model (pulsar_simple: 15 DoF + 10 modes, a tile payload)."""

from __future__ import annotations

import numpy as np
import pytest

from sms_cli.model.model_errors import follow_payloads, law_model
import sms_cli.sim.compiled.ndi_law as K

from test_compiled_ndi import pulsar  # noqa: F401  (the flagship's model, a module fixture)


def _state(sm, seed):
    rng = np.random.default_rng(seed)
    q = sm.q0.copy()
    q[[a.q_index for a in sm.arm]] += rng.normal(scale=0.3, size=len(sm.arm))
    v = rng.normal(scale=0.05, size=sm.nv)
    return q, v, rng.normal(scale=0.01, size=sm.n_modes), rng.normal(scale=0.01, size=sm.n_modes)


def _r(sm, q, v, eta, etadot):
    return sm.bias_forces(q, v, etadot) - sm.internal_forces(q, v, eta, etadot)


def test_a_law_model_without_errors_is_the_plant(pulsar):
    law = law_model(pulsar)
    for seed in range(3):
        q, v, eta, etadot = _state(pulsar, seed)
        M = pulsar.mass_matrix(q)
        assert np.allclose(law.mass_matrix(q), M, rtol=0, atol=1e-13 * np.abs(M).max())  # round-off of the re-attached tile
        r = _r(pulsar, q, v, eta, etadot)
        assert np.allclose(_r(law, q, v, eta, etadot), r, rtol=0, atol=1e-13 * np.abs(r).max())


def test_each_body_gets_the_stated_errors_and_the_mass_is_kept(pulsar):
    """Every body: mass equal, CoM scaled by 1 ± 10 %, rotational inertia about the CoM by 1 ± 3 %, both signs
    drawn across the bodies; every mode's frequency +10 %, participation factors and damping ratios equal."""
    law = law_model(pulsar, inertia=0.03, com=0.10, modal_frequency=0.10, seed=4)
    signs_I, signs_c = set(), set()
    for j in range(1, pulsar.model.njoints):
        Y, Z = pulsar.model.inertias[j], law.model.inertias[j]
        if pulsar.payloads and any(p.attached and p.joint_id == j for p in pulsar.payloads.values()):
            continue  # a body carrying a payload: the next test
        assert Z.mass == pytest.approx(Y.mass, rel=1e-14)
        if np.linalg.norm(Y.lever) > 1e-9:
            ratio = np.linalg.norm(Z.lever) / np.linalg.norm(Y.lever)
            assert min(abs(ratio - 1.1), abs(ratio - 0.9)) < 1e-12
            signs_c.add(round(float(ratio), 6))
            assert np.allclose(np.cross(Z.lever, Y.lever), 0, atol=1e-14)  # same direction
        ratio_I = np.linalg.norm(Z.inertia) / np.linalg.norm(Y.inertia)
        assert min(abs(ratio_I - 1.03), abs(ratio_I - 0.97)) < 1e-12
        assert np.allclose(Z.inertia, ratio_I * Y.inertia, rtol=1e-13, atol=1e-15)
        signs_I.add(round(float(ratio_I), 6))
    assert signs_I == {0.97, 1.03} and signs_c == {0.9, 1.1}
    assert law.total_mass == pytest.approx(pulsar.total_mass, rel=1e-14)
    for a, b in zip(pulsar.appendages, law.appendages):
        assert np.allclose(b.omega, 1.1 * a.omega, rtol=1e-15)
        assert np.array_equal(b.L, a.L) and np.array_equal(b.zeta, a.zeta)


def test_payloads_stay_nominal_and_follow_the_plant(pulsar):
    """The errors are on the robot: the law's copy made with the tile attached, once the tile is released, has the
    same bodies as the copy made without it; follow_payloads mirrors the plant's attach/release."""
    name = next(iter(pulsar.payloads))
    assert pulsar.payloads[name].attached
    with_tile = law_model(pulsar, inertia=0.03, com=0.10, seed=2)
    pulsar.detach_payload(name)
    try:
        without = law_model(pulsar, inertia=0.03, com=0.10, seed=2)
        assert follow_payloads(with_tile, pulsar) and not with_tile.payloads[name].attached
        assert not follow_payloads(with_tile, pulsar)
        for j in range(1, pulsar.model.njoints):
            assert np.allclose(with_tile.model.inertias[j].toDynamicParameters(),
                               without.model.inertias[j].toDynamicParameters(), rtol=1e-12, atol=1e-12)
    finally:
        pulsar.attach_payload(name)
    assert follow_payloads(with_tile, pulsar) and with_tile.payloads[name].attached


def _split(sm, q, v, eta_hat, etadot_hat, omega, tau, tau_hat=None):
    """torque_split at the estimated state x̂ (ω0 = omega, η̂, η̂̇) as the law evaluates it."""
    ix = sm.reduced.ix
    M = sm.mass_matrix(q)
    x = np.zeros(sm.nx)
    x_hat = np.r_[eta_hat, omega, etadot_hat]
    flags = np.zeros(K.N_FLAGS, dtype=np.int64)
    flags[K.STARTED] = 1
    K.ndi_velocity(M, ix.base_linear, ix.base_angular, ix.actuators, ix.flexible, omega, v, x_hat, flags, x)
    r = _r(sm, q, x[:sm.nv], eta_hat, x[sm.nv:])
    x_lin = np.zeros(sm.nx)
    K.rigid_velocity(M, ix.base_linear, ix.base_angular, ix.actuators, ix.flexible, v, x_lin)
    zero = np.zeros(sm.n_modes)
    r_lin = _r(sm, q, x_lin[:sm.nv], zero, zero)
    split = np.zeros((3, ix.actuators.size))
    th = np.zeros(ix.actuators.size) if tau_hat is None else tau_hat
    sets = (ix.base_linear, ix.base_angular, ix.actuators, ix.flexible)
    _, n_term, sol = K.actuator_dynamics(M, r, *sets)
    K.torque_split(n_term, K.reduced_bias(sol, r_lin, *sets), th, tau_hat is not None, tau, split)
    return split, M, r, r_lin, x_lin


def test_the_linearising_torque_holds_the_actuator_rates_of_the_rigid_motion(pulsar):
    """Applied alone at the rigid-motion state (the actuators' rates, ω0 = 0, η = η̇ = 0, zero linear momentum),
    the linearising part gives zero actuator accelerations: M ẍ + r_lin = [0; τ_lin; 0] solved in full."""
    sm = pulsar
    ix = sm.reduced.ix
    for seed in range(3):
        q, v, eta, etadot = _state(sm, seed)
        split, M, _, r_lin, x_lin = _split(sm, q, v, eta, etadot, v[3:6], np.zeros(ix.actuators.size))
        assert np.allclose(x_lin[ix.base_angular], 0) and np.allclose(x_lin[ix.flexible], 0)
        assert np.allclose(x_lin[ix.actuators], v[ix.actuators])
        assert abs((M[ix.base_linear] @ x_lin)).max() < 1e-12 * max(1.0, abs(M @ x_lin).max())
        rhs = -r_lin
        rhs[ix.actuators] += split[1]
        xdd = np.linalg.solve(M, rhs)
        assert np.abs(xdd[ix.actuators]).max() < 1e-10 * max(1.0, np.abs(r_lin).max())
        assert np.abs(split[1]).max() > 0


def test_the_disturbance_torque_is_the_estimated_states_and_the_ndo(pulsar):
    """With no estimated flexible or base motion (x̂_e = 0) the disturbance part is zero, or exactly −τ̂_d with the
    disturbance observer on; with an estimated state, it is what that state adds to n."""
    sm = pulsar
    na = sm.reduced.ix.actuators.size
    q, v, eta, etadot = _state(sm, 7)
    zero = np.zeros(sm.n_modes)
    tau = np.random.default_rng(1).normal(size=na)
    split, *_ = _split(sm, q, v, zero, zero, np.zeros(3), tau)
    assert np.abs(split[2]).max() < 1e-12 * np.abs(split[1]).max()
    tau_hat = np.random.default_rng(2).normal(size=na)
    split_d, *_ = _split(sm, q, v, zero, zero, np.zeros(3), tau, tau_hat)
    assert np.allclose(split_d[2], -tau_hat, rtol=0, atol=1e-12)
    assert np.allclose(split_d[0], split[0] + tau_hat, rtol=0, atol=1e-12)
    split_e, *_ = _split(sm, q, v, eta, etadot, v[3:6], tau)
    assert np.abs(split_e[2]).max() > 1e-3 * np.abs(split_e[1]).max()
    assert np.allclose(split_e.sum(axis=0), tau, rtol=0, atol=1e-12)


def test_the_feedback_torque_is_the_commanded_accelerations_torque(pulsar):
    """Unsaturated, the feedback part is M◇ v: M◇⁻¹ (from Pinocchio's mass matrix) of it gives the arm's commands
    q̈_d + kp ε + kv ε̇."""
    sm = pulsar
    ix = sm.reduced.ix
    rng = np.random.default_rng(3)
    q, v, eta, etadot = _state(sm, 3)
    n_r, n_m = len(sm.wheels), len(sm.arm)
    na = n_r + n_m
    M = sm.mass_matrix(q)
    x_hat = np.r_[eta, v[3:6], etadot]
    flags = np.zeros(K.N_FLAGS, dtype=np.int64)
    flags[K.STARTED] = 1
    x = np.zeros(sm.nx)
    K.ndi_velocity(M, ix.base_linear, ix.base_angular, ix.actuators, ix.flexible, v[3:6].copy(), v, x_hat, flags, x)
    r = _r(sm, q, x[:sm.nv], eta, x[sm.nv:])
    kp, kv = np.r_[np.ones(n_r), rng.uniform(0.1, 1, n_m)], np.r_[np.ones(n_r), rng.uniform(0.1, 1, n_m)]
    q_arm = q[[a.q_index for a in sm.arm]]
    ref_q, ref_qd, ref_qdd = q_arm + rng.normal(scale=0.1, size=n_m), rng.normal(size=n_m), rng.normal(size=n_m)
    pinv, wrr, tau = np.zeros((n_r, 3)), np.zeros(n_r), np.zeros(na)
    M_dia, n_term, sol = K.actuator_dynamics(M, r, ix.base_linear, ix.base_angular, ix.actuators, ix.flexible)
    K.ndi_command(M, M_dia, n_term, sol, ix.base_angular, ix.actuators, n_r, kp, kv, 0.05, True,
                  np.full(n_r, 1e9), q[3:7].copy(), v[3:6].copy(), v, q_arm, np.array([0.0, 0, 0, 1]), np.zeros(3), ref_q,
                  ref_qd, ref_qdd, flags, pinv, wrr, tau)
    split, *_ = _split(sm, q, v, eta, etadot, v[3:6].copy(), tau)
    a, u = ix.actuators, np.r_[ix.base_linear, ix.base_angular, ix.flexible]
    M_dia = M[np.ix_(a, a)] - M[np.ix_(a, u)] @ np.linalg.solve(M[np.ix_(u, u)], M[np.ix_(u, a)])
    v_cmd = np.linalg.solve(M_dia, split[0])
    v_arm = ref_qdd + kp[n_r:] * (ref_q - q_arm) + kv[n_r:] * (ref_qd - v[a[n_r:]])
    assert np.allclose(v_cmd[n_r:], v_arm, rtol=1e-9, atol=1e-9 * np.abs(v_arm).max())


def test_both_loops_agree_with_model_errors_and_the_disturbance_observer(tmp_path, pulsar):
    """The flagship's shortened run (tile released between moves) with the law's model in error by Kraiem 2022
    §4.3's bounds and the disturbance observer on: the Python loop (Pinocchio on the law's copy) and the compiled loop
    (the copy's flattened tree) agree to 1e-9 on status, metrics (the torque split's included) and every recorded
    message; the errors change the run, and the observer then estimates a nonzero disturbance."""
    import json

    from test_compiled_arm import _compare_missions_text
    from test_compiled_ndi import FLAGSHIP, _gains, _mission_text

    ix = pulsar.reduced.ix
    M = pulsar.mass_matrix(pulsar.q0)
    a, u = ix.actuators, np.r_[ix.base_linear, ix.base_angular, ix.flexible]
    M_dia = M[np.ix_(a, a)] - M[np.ix_(a, u)] @ np.linalg.solve(M[np.ix_(u, u)], M[np.ix_(u, a)])
    base = dict(_gains(pulsar), disturbance_observer=True, Q_d=(0.5 * M_dia).tolist())
    erroneous = dict(base, model_errors={"inertia": 0.03, "com": 0.1, "modal_frequency": 0.1, "seed": 1})
    (tmp_path / "errors").mkdir()
    (tmp_path / "exact").mkdir()
    # then a free-floating phase: the law is off, its split is traced as zero in both loops
    phases = FLAGSHIP + "    - {name: drift, kind: hold, duration: 1 s, base_mode: free-floating}\n"
    py, _ = _compare_missions_text(tmp_path / "errors", lambda e: _mission_text("pulsar_simple.yaml", e, phases, erroneous))
    exact, _ = _compare_missions_text(tmp_path / "exact", lambda e: _mission_text("pulsar_simple.yaml", e, FLAGSHIP, base))
    transfer = lambda res: next(p for p in res["phases"] if p["name"] == "transfer")  # noqa: E731
    split, split_exact = transfer(py)["torque_split"], transfer(exact)["torque_split"]
    assert split["arm"]["linearising_to_feedback"] > 0 and split["arm"]["disturbance_to_linearising"] > 0
    # wheels on the base: no linearising torque about their axes (round-off, left out of the ratio)
    assert max(split["wheels"]["linearising_peak"]) < 1e-8 * max(split["wheels"]["feedback_peak"])
    assert split["wheels"]["disturbance_to_linearising"] is None
    # the disturbance observer takes up the model errors: the disturbance part grows by orders of magnitude
    assert max(split["wheels"]["disturbance_peak"]) > 1e3 * max(split_exact["wheels"]["disturbance_peak"])
    assert json.dumps(split) != json.dumps(split_exact)
    assert transfer(py)["joint_rate_error_rel_max"] != transfer(exact)["joint_rate_error_rel_max"]
    assert next(p for p in py["phases"] if p["name"] == "drift")["torque_split"] is None
