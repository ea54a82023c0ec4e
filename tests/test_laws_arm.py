"""Arm laws against oracles: the closed-form response of a PD-controlled joint, the SMC reaching
bound and sliding decay, and computed torque on the SystemModel of tests/data/arm3.yaml (free-
floating, with modes and wheels) following the designed linear error dynamics exactly."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest
from scipy.integrate import solve_ivp

from sms_cli.dynamics.integrator import State, rkmk4_step
from sms_cli.errors import InputError
from sms_cli.sim.interfaces import ArmRef, Sensed
from sms_cli.sim.laws.arm import ComputedTorque, ComputedTorqueSMC, JointPD, JointSMC
from sms_cli.sim.laws.plant_models import ArmDynamics

from conftest import DATA, compile_path, sm_sensed


def joint_sensed(t, q, qd):
    n = np.size(q)
    return Sensed(t=t, quat=np.array([0, 0, 0, 1.0]), omega=np.zeros(3), position=np.zeros(3), velocity=np.zeros(3),
                  q_arm=np.atleast_1d(q).astype(float), qd_arm=np.atleast_1d(qd).astype(float),
                  wheel_speed=np.zeros(0), q=np.zeros(7 + n), v=np.zeros(6 + n))





# ----------------------------------------------------------------------------- Chevallard 2019 joint PD
@pytest.mark.parametrize("kp,kd", [(1.0, 100.0), (0.7, 90.0), (0.5, 50.0)])  # Table 6.3 gain sets (L1114-1126)
def test_cascaded_joint_pd_matches_the_closed_form_step_response(kp, kd):
    I = 120.0  # kg m² about the joint
    law = JointPD(kp, kd)
    qd = 0.8
    wn, zeta = math.sqrt(kd * kp / I), kd / (2 * math.sqrt(kd * kp * I))

    def f(t, y):
        return [y[1], law.torque(joint_sensed(t, y[0], y[1]), ArmRef(np.array([qd]), np.zeros(1), np.zeros(1)))[0] / I]

    sol = solve_ivp(f, (0, 30), [0.0, 0.0], rtol=1e-11, atol=1e-13, dense_output=True)
    ts = np.linspace(0, 30, 61)
    if zeta > 1:
        r1, r2 = -wn * (zeta - math.sqrt(zeta**2 - 1)), -wn * (zeta + math.sqrt(zeta**2 - 1))
        e = qd * (r2 * np.exp(r1 * ts) - r1 * np.exp(r2 * ts)) / (r2 - r1)
    else:
        wd = wn * math.sqrt(1 - zeta**2)
        e = qd * np.exp(-zeta * wn * ts) * (np.cos(wd * ts) + zeta * wn / wd * np.sin(wd * ts))
    assert np.max(np.abs(qd - sol.sol(ts)[0] - e)) < 1e-8


def test_joint_pd_rate_feedforward_tracks_a_ramp_without_lag():
    law = JointPD(0.5, 20.0)
    ref = ArmRef(np.array([1.0]), np.array([0.1]), np.zeros(1))
    tau = law.torque(joint_sensed(0, 1.0, 0.1), ref)
    assert tau == pytest.approx([0.0])
    lagging = JointPD(0.5, 20.0, rate_feedforward=False).torque(joint_sensed(0, 1.0, 0.1), ref)
    assert lagging == pytest.approx([-2.0])


def test_continuous_joint_error_is_wrapped():
    law = JointPD(1.0, 1.0, wrap=[True])
    ref = ArmRef(np.array([math.radians(-180)]), np.zeros(1), np.zeros(1))
    tau = law.torque(joint_sensed(0, math.radians(170), 0), ref)
    assert tau[0] == pytest.approx(math.radians(10))


# ----------------------------------------------------------------------------- Ruggiero 2020 joint SMC
def test_joint_smc_reaches_the_surface_in_time_then_slides_at_rate_lambda():
    I, k, lam = 0.02, 0.01, 0.3  # k/I = 0.5 rad/s²
    law = JointSMC(k, lam, smoothing="sign")
    ref = ArmRef(np.array([1.0]), np.zeros(1), np.zeros(1))
    dt, q, w, t = 1e-4, 0.0, 0.0, 0.0
    sig0 = law.surface(joint_sensed(0, q, w), ref)[0]
    hist = []
    while t < 14.0:
        tau = law.torque(joint_sensed(t, q, w), ref)[0]
        w_new = w + tau / I * dt  # exact for a held torque on a double integrator
        q += 0.5 * (w + w_new) * dt
        w, t = w_new, t + dt
        hist.append((t, q, law.surface(joint_sensed(t, q, w), ref)[0]))
    # σ̇ = λ q̇ + τ/I, |λ q̇| ≤ λ k/I t: bound for the reaching time of the ideal law
    A = lam * max(abs((hist[i][1] - hist[i - 1][1]) / dt) for i in range(1, len(hist)))
    t_reach = next(t for t, _, s in hist if abs(s) < 2 * k / I * dt)
    assert t_reach <= abs(sig0) / (k / I - A) + dt
    e = {round(t, 4): 1.0 - q for t, q, _ in hist}
    assert t_reach < 2.0
    t1, t2 = round(t_reach + 1, 1), round(t_reach + 11, 1)
    assert e[t2] / e[t1] == pytest.approx(math.exp(-lam * (t2 - t1)), rel=1e-2)
    assert max(abs(law.torque(joint_sensed(0, x, 0), ref)[0]) for x in (-5, 0.5, 3)) <= k


# ----------------------------------------------------------------------------- computed torque on arm3
def _reference(sm, t):
    q0 = sm.q0[sm.idx.q_arm]
    A, w = np.array([0.3, -0.2, 0.25]), np.array([0.7, 0.9, 1.1])
    return ArmRef(q0 + A * np.sin(w * t), A * w * np.cos(w * t), -A * w**2 * np.sin(w * t))


def _run_ct(sm, law, T=6.0, dt=1e-3, e0=np.array([0.05, -0.04, 0.03])):
    st = State(sm.q0.copy(), sm.v0.copy(), sm.eta0.copy(), sm.etadot0.copy())
    st.q[sm.idx.q_arm] -= e0  # q_d(0) − q(0) = e0, ė(0) = q̇_d(0)
    t = 0.0
    out = []

    def accel(t):
        def a(q, v, eta, etadot):
            tau = np.zeros(sm.nv)
            s = sm_sensed(sm, t, State(q, v, eta, etadot))
            tau[sm.idx.arm] = law.torque(s, _reference(sm, t))
            return sm.forward_dynamics(q, v, eta, etadot, tau)
        return a

    for _ in range(int(round(T / dt))):
        ref = _reference(sm, t)
        out.append((t, ref.q - st.q[sm.idx.q_arm], ref.qd - st.v[sm.idx.arm], st.v[3:6].copy()))
        # law evaluated at each stage time: RKMK4 stage times are t, t+dt/2, t+dt/2, t+dt
        stage = iter([t, t + dt / 2, t + dt / 2, t + dt])
        st = rkmk4_step(sm.model, st, dt, lambda q, v, e, ed: accel(next(stage))(q, v, e, ed))
        t += dt
    return out


def _closed_form(kp, kd, e0, ed0, t):
    """ë + kd ė + kp e = 0 per joint (distinct real or complex roots)."""
    r = np.roots([1.0, kd, kp])
    c2 = (ed0 - r[0] * e0) / (r[1] - r[0])
    c1 = e0 - c2
    return float(np.real(c1 * np.exp(r[0] * t) + c2 * np.exp(r[1] * t)))


def test_computed_torque_free_floating_gives_the_designed_error_dynamics(arm3):
    kp, kd = np.array([4.0, 6.0, 9.0]), np.array([3.0, 4.0, 5.0])
    out = _run_ct(arm3, ComputedTorque(arm3, kp, kd, "free_floating"))
    e0 = out[0][1]
    ed0 = out[0][2]
    worst = 0.0
    for t, e, _, _ in out[::500]:
        for j in range(3):
            worst = max(worst, abs(e[j] - _closed_form(kp[j], kd[j], e0[j], ed0[j], t)))
    assert worst < 1e-8
    assert max(np.linalg.norm(w) for *_, w in out) > 1e-3  # the base really rotated (free-floating, coupled)


def test_computed_torque_fixed_base_model_on_a_heavy_base(arm3):
    """Fixed-base model (joint rows of H) is exact in the limit of an immovable base."""
    sm = compile_path(DATA / "arm3.yaml")
    Y = sm.model.inertias[1]
    sm.model.inertias[1] = pin.Inertia(Y.mass * 1e7, Y.lever, Y.inertia * 1e7)
    kp, kd = np.full(3, 4.0), np.full(3, 5.0)
    out = _run_ct(sm, ComputedTorque(sm, kp, kd, "fixed_base"), T=4.0)
    e0, ed0 = out[0][1], out[0][2]
    worst = max(abs(e[j] - _closed_form(kp[j], kd[j], e0[j], ed0[j], t)) for t, e, *_ in out[::400] for j in range(3))
    assert worst < 1e-5
    # and the fixed-base model is not exact on the real (free-floating) arm3
    out = _run_ct(arm3, ComputedTorque(arm3, kp, kd, "fixed_base"), T=4.0)
    worst = max(abs(e[j] - _closed_form(kp[j], kd[j], e0[j], ed0[j], t)) for t, e, *_ in out[::400] for j in range(3))
    assert worst > 1e-4


def test_arm_dynamics_free_floating_matches_forward_dynamics(arm3):
    """τ = M* q̈ + h* inverts the plant: forward dynamics of that τ returns q̈ (free base, idle wheels)."""
    sm = arm3
    rng = np.random.default_rng(2)
    st = State(sm.q0.copy(), rng.normal(size=sm.nv) * 0.1, rng.normal(size=sm.n_modes) * 0.01,
               rng.normal(size=sm.n_modes) * 0.01)
    s = sm_sensed(sm, 0.0, st)
    M, h = ArmDynamics(sm, "free_floating").terms(s)
    qdd = rng.normal(size=3)
    tau = np.zeros(sm.nv)
    tau[sm.idx.arm] = M @ qdd + h
    vdot, _ = sm.forward_dynamics(st.q, st.v, st.eta, st.etadot, tau)
    assert np.allclose(vdot[sm.idx.arm], qdd, atol=1e-10)
    assert np.all(np.linalg.eigvalsh(M) > 0)


# ----------------------------------------------------------------------------- Caldera 2019 joint SMC
def test_smc_computed_torque_surface_obeys_its_reaching_law(arm3):
    """ṡ = −(k1 − λ) s − c tanh(μ s) per joint (exact model), critically damped k1² = 4 k2."""
    k1 = np.array([0.8, 1.0, 1.2])
    k2 = k1**2 / 4
    c, mu = 0.05, 5.0
    law = ComputedTorqueSMC(arm3, k1, k2, c, mu, "free_floating")
    out = _run_ct(arm3, law, T=5.0)
    lam = law.lam
    assert np.allclose(lam, k1 / 2)
    s0 = out[0][2] + lam * out[0][1]
    for j in range(3):
        ref = solve_ivp(lambda t, s: -(k1[j] - lam[j]) * s - c * np.tanh(mu * s), (0, 5), [s0[j]], rtol=1e-12,
                        atol=1e-14, dense_output=True)
        for t, e, ed, _ in out[::500]:
            assert ed[j] + lam[j] * e[j] == pytest.approx(ref.sol(t)[0], abs=1e-8)


def test_smc_computed_torque_rejects_underdamped_gains(arm3):
    with pytest.raises(ValueError, match="critically damped"):
        ComputedTorqueSMC(arm3, 0.05, 0.01, 0.0)


# ----------------------------------------------------------------------------- specs and factories
def test_factories_build_every_arm_law_and_report_bad_lengths(arm3):
    from pydantic import TypeAdapter

    from sms_cli.sim.laws import ArmLawSpec, build_arm_law

    ta = TypeAdapter(ArmLawSpec)
    specs = [
        {"law": "joint_pd", "kp": 1.0, "kd": [100, 90, 50]},
        {"law": "smc", "k": 0.5, "lambda": 0.2},
        {"law": "computed_torque", "kp": 0.04, "kd": 0.4, "model": "attitude_held"},
        {"law": "smc_computed_torque", "k1": 0.058, "k2": 8.41e-4, "c": 0.001},
    ]
    s = sm_sensed(arm3, 0.0, State(arm3.q0.copy(), arm3.v0.copy(), arm3.eta0.copy(), arm3.etadot0.copy()))
    ref = ArmRef(arm3.q0[arm3.idx.q_arm] + 0.1, np.zeros(3), np.zeros(3))
    for d in specs:
        law = build_arm_law(ta.validate_python(d), arm3)
        tau = law.torque(s, ref)
        assert tau.shape == (3,) and np.all(np.isfinite(tau))
    with pytest.raises(InputError, match="expected one value or 3 values"):
        build_arm_law(ta.validate_python({"law": "joint_pd", "kp": [1, 2], "kd": 1}), arm3)
    with pytest.raises(InputError, match="critically damped"):
        build_arm_law(ta.validate_python({"law": "smc_computed_torque", "k1": 0.01, "k2": 1.0}), arm3)
