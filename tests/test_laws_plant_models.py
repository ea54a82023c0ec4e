"""Model quantities the laws use, against independent computations (Pinocchio's centroidal
composite inertia, Basilisk's wheel momentum h_s), and a Caldera 2019 S1 run on the SystemModel."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from sms_cli.dynamics.integrator import State, rkmk4_step
from sms_cli.sim.interfaces import ArmRef, AttitudeRef
from sms_cli.sim.laws.arm import ComputedTorque
from sms_cli.sim.laws.attitude import SlidingModeAttitude, TrackingError
from sms_cli.sim.laws.plant_models import SystemBody, base_rotation, effective_inertia

from conftest import MISSIONS, compile_path, sm_sensed





def test_effective_inertia_is_the_centroidal_inertia_minus_wheel_spin(arm3):
    sm = arm3
    q = sm.q0.copy()
    pin.ccrba(sm.model, sm.data, q, np.zeros(sm.nv))
    R = base_rotation(q[3:7])
    Ig = R.T @ sm.data.Ig.inertia @ R  # locked CoM-centred inertia, base frame
    spin = sum(w.spin_inertia * np.outer(w.axis, w.axis) for w in sm.wheels)
    assert np.allclose(effective_inertia(sm, q), Ig - spin, atol=1e-10)


def test_internal_momentum_is_basilisk_wheel_momentum_when_the_arm_is_still(arm3):
    sm = arm3
    rng = np.random.default_rng(7)
    v = np.zeros(sm.nv)
    v[0:3] = rng.normal(size=3) * 0.1  # base linear velocity: no effect on momentum about the CoM
    v[3:6] = rng.normal(size=3) * 0.05
    v[sm.idx.wheels] = rng.normal(size=len(sm.wheels)) * 100
    st = State(sm.q0.copy(), v, sm.eta0.copy(), sm.etadot0.copy())
    s = sm_sensed(sm, 0.0, st)
    body = SystemBody(sm)
    hs = sum(w.axis * w.spin_inertia * (w.axis @ s.omega + s.wheel_speed[i]) for i, w in enumerate(sm.wheels))
    assert np.allclose(body.internal_momentum(s), hs, atol=1e-10)
    assert np.allclose(body.inertia_rate(s), 0.0, atol=1e-6)  # only base and wheels move: J constant


def test_inertia_rate_matches_the_change_of_inertia_along_an_arm_motion(arm3):
    sm = arm3
    body = SystemBody(sm)
    v = np.zeros(sm.nv)
    v[sm.idx.arm] = [0.2, -0.3, 0.4]
    st = State(sm.q0.copy(), v, sm.eta0.copy(), sm.etadot0.copy())
    Jd = body.inertia_rate(sm_sensed(sm, 0.0, st))
    dt = 1e-3
    J1 = effective_inertia(sm, pin.integrate(sm.model, sm.q0, dt * v))
    J0 = effective_inertia(sm, pin.integrate(sm.model, sm.q0, -dt * v))
    assert np.allclose(Jd, (J1 - J0) / (2 * dt), atol=1e-6 * np.abs(Jd).max())
    assert np.abs(Jd).max() > 1e-3


def test_seed000_scenario1_slew_on_the_system_model_settles_in_the_thesis_band():
    """Caldera S1 (L805-822): [π/3]³ slew, arm held straight up, 4 pyramid wheels clipped at
    0.4 N m, SMC k = 0.08, c = 0.01, μ = 20: < 1° after ≈ 120 s (band [90, 160] s, notes §5.3)."""
    sm = compile_path(MISSIONS / "caldera_smallsat.yaml")
    sm.q0[sm.idx.q_arm] = [0.0, math.pi / 2, 0.0]
    st = State(sm.q0.copy(), sm.v0.copy(), sm.eta0.copy(), sm.etadot0.copy())
    qref = np.array([0.15849365, 0.59150635, 0.15849365, 0.77451905])
    law = SlidingModeAttitude(0.08, 0.01, 20.0, SystemBody(sm, online=False))
    hold = ComputedTorque(sm, 1.0, 2.0, "attitude_held")
    A = np.array([w.axis for w in sm.wheels]).T
    Ap = np.linalg.pinv(A)
    umax = np.array([w.max_torque for w in sm.wheels])
    ref, aref = AttitudeRef(qref), ArmRef(np.array([0.0, math.pi / 2, 0.0]), np.zeros(3), np.zeros(3))
    t, last_out, dt = 0.0, 0.0, 0.01
    while t < 200.0 - 1e-9:
        s = sm_sensed(sm, t, st)
        if TrackingError(s, ref).angle() > math.radians(1):
            last_out = t
        tau = np.zeros(sm.nv)
        tau[sm.idx.wheels] = np.clip(-Ap @ law.torque(s, ref), -umax, umax)  # motor torques: A τ_w = −T
        tau[sm.idx.arm] = hold.torque(s, aref)
        for _ in range(10):  # 10 Hz control, 100 Hz plant
            st = rkmk4_step(sm.model, st, dt, lambda q, v, e, ed: sm.forward_dynamics(q, v, e, ed, tau))
            t += dt
    assert 90.0 <= last_out <= 160.0
    assert TrackingError(sm_sensed(sm, t, st), ref).angle() < math.radians(0.05)
