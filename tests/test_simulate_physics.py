"""Simulator physics against oracles: conservation with the integrator's order, wheel spin-up in
closed form, exact saturation, and a hinged panel's closed-form coupled frequency."""

from __future__ import annotations

import math

import numpy as np
import pytest

from conftest import DATA, MISSIONS, compile_path
from sms_cli.dynamics.integrator import State, rkmk4_step


@pytest.fixture(scope="module")
def chaser():
    return compile_path(MISSIONS / "chevallard_chaser.yaml")


def _torque_profile(sm, t):
    tau = np.zeros(sm.nv)
    k = np.arange(1, len(sm.arm) + 1)
    tau[sm.idx.arm] = 0.5 * np.sin(0.5 * k * t + k) / k
    return tau


def _run(sm, v0, T, dt, torques=True):
    s = State(sm.q0.copy(), v0.copy(), np.zeros(0), np.zeros(0))
    zero = np.zeros(sm.nv)
    for k in range(int(round(T / dt))):
        tau = _torque_profile(sm, k * dt) if torques else zero
        s = rkmk4_step(sm.model, s, dt, lambda q, v, e, ed: sm.forward_dynamics(q, v, e, ed, tau))
    return s


def _initial_velocity(sm):
    v = np.zeros(sm.nv)
    v[:6] = [0.01, -0.02, 0.015, 0.02, -0.01, 0.03]
    v[sm.idx.arm] = 0.05
    return v


def _drift(sm, s0_v, s1):
    p0, k0 = sm.momentum(sm.q0, s0_v, about="origin")
    p1, k1 = sm.momentum(s1.q, s1.v, about="origin")
    return np.linalg.norm(p1 - p0) / np.linalg.norm(p0), np.linalg.norm(k1 - k0) / np.linalg.norm(k0)


def test_free_floating_chaser_momentum_20s_internal_torques(chaser):
    v0 = _initial_velocity(chaser)
    s = _run(chaser, v0, T=20.0, dt=0.001)
    dp, dk = _drift(chaser, v0, s)
    assert dp <= 1e-9 and dk <= 1e-9, (dp, dk)


def test_free_floating_chaser_energy_20s_no_torque(chaser):
    v0 = _initial_velocity(chaser)
    e0 = chaser.energy(chaser.q0, v0, np.zeros(0), np.zeros(0))
    s = _run(chaser, v0, T=20.0, dt=0.001, torques=False)
    e1 = chaser.energy(s.q, s.v, np.zeros(0), np.zeros(0))
    assert abs(e1 - e0) / e0 <= 1e-9


def test_fourth_order_convergence(chaser):
    """At coarse steps (error well above round-off) halving dt divides the errors by ≈ 16."""
    v0 = _initial_velocity(chaser) * 5.0
    errs_p, errs_e = [], []
    e0 = chaser.energy(chaser.q0, v0, np.zeros(0), np.zeros(0))
    for dt in (0.02, 0.01, 0.005):
        s = _run(chaser, v0, T=4.0, dt=dt)
        errs_p.append(max(_drift(chaser, v0, s)))
        s = _run(chaser, v0, T=4.0, dt=dt, torques=False)
        errs_e.append(abs(chaser.energy(s.q, s.v, np.zeros(0), np.zeros(0)) - e0) / e0)
    for errs in (errs_p, errs_e):
        ratios = [a / b for a, b in zip(errs, errs[1:])]
        assert all(10.0 < r < 24.0 for r in ratios), (errs, ratios)


def _hub_with_wheel(tmp_path, wheel_mass=0.0):
    (tmp_path / "hub.urdf").write_text(
        '<robot name="hub"><link name="hub"><inertial><mass value="50"/>'
        '<inertia ixx="5" iyy="6" izz="7" ixy="0" ixz="0" iyz="0"/></inertial></link></robot>')
    (tmp_path / "m.yaml").write_text(
        "name: hub\nrobot: {urdf: hub.urdf, arm_joints: []}\n"
        "wheels:\n  declared:\n    - {name: rw, axis: [0, 0, 1], spin_inertia: 0.1, transverse_inertia: 0.05,"
        f" mass: {wheel_mass}, max_torque: 0.5, max_speed: 100}}\n")
    return compile_path(tmp_path / "m.yaml")


def test_wheel_spin_up_closed_form(tmp_path):
    """Constant motor torque u on a wheel of a free hub: the hub rate is ω(t) = ω0 − u t / I, with I the
    hub inertia about the axis excluding the rotor's spin inertia (Euler's equations, no coupling)."""
    sm = _hub_with_wheel(tmp_path)
    u, w0 = 0.2, 0.01
    v = np.zeros(sm.nv)
    v[5] = w0
    s = State(sm.q0.copy(), v, np.zeros(0), np.zeros(0))
    tau = np.zeros(sm.nv)
    tau[sm.idx.wheels] = u
    I_hub = 7.0 + 0.05 * 0  # rotor transverse inertia is about x/y, not z
    for k in range(1, 201):
        s = rkmk4_step(sm.model, s, 0.05, lambda q, vv, e, ed: sm.forward_dynamics(q, vv, e, ed, tau))
        t = 0.05 * k
        assert s.v[5] == pytest.approx(w0 - u * t / I_hub, abs=1e-12)
        # wheel absolute speed grows by u t / I_spin
        assert s.v[5] + s.v[sm.idx.wheels][0] == pytest.approx(w0 + u * t / 0.1, rel=1e-12)


def test_wheel_torque_and_speed_saturation_clip_exactly(tmp_path):
    from sms_cli.sim.actuators import WheelArray
    from sms_cli.sim.schema import AllocationSpec, WheelFriction

    sm = _hub_with_wheel(tmp_path)
    wa = WheelArray(sm, AllocationSpec(), WheelFriction())
    clipped, flags = wa.clip_torque(np.array([2.0]))
    assert clipped[0] == 0.5 and flags[0]
    clipped, flags = wa.clip_torque(np.array([-0.3]))
    assert clipped[0] == -0.3 and not flags[0]
    wa.update_effective_inertia(sm.q0)
    s = State(sm.q0.copy(), np.zeros(sm.nv), np.zeros(0), np.zeros(0))
    dt = 0.1
    top = 0.0
    for _ in range(400):
        cmd = wa.speed_limited(wa.clip_torque(np.array([0.5]))[0], s.v[sm.idx.wheels], dt)
        tau = np.zeros(sm.nv)
        tau[sm.idx.wheels] = cmd
        s = rkmk4_step(sm.model, s, dt, lambda q, vv, e, ed: sm.forward_dynamics(q, vv, e, ed, tau))
        top = max(top, s.v[sm.idx.wheels][0])
    assert top == pytest.approx(100.0, rel=1e-9)  # reaches the limit and never exceeds it
    assert s.v[sm.idx.wheels][0] == pytest.approx(100.0, rel=1e-9)


def test_hinged_panel_oscillates_at_closed_form_coupled_frequency():
    """Hub (50 kg, diag(5,6,7)) + 10 kg panel hinged about x at (0, 0.5, 0), CoM 1 m further along y,
    I_cm diag(1, 0.1, 1), spring k = 20 N m/rad. Closed form (plain numpy, no Pinocchio):
    ω² = k / (I_aa − bᵀ M⁻¹ b) with M the locked 6×6 inertia about the origin, b the hinge coupling."""
    m_h, m_p, k = 50.0, 10.0, 20.0
    c_p = np.array([0.0, 1.5, 0.0])
    hinge, a = np.array([0.0, 0.5, 0.0]), np.array([1.0, 0.0, 0.0])

    def skew(x):
        return np.array([[0, -x[2], x[1]], [x[2], 0, -x[0]], [-x[1], x[0], 0]])

    I_p_origin = np.diag([1.0, 0.1, 1.0]) + m_p * (c_p @ c_p * np.eye(3) - np.outer(c_p, c_p))
    M = np.zeros((6, 6))  # [v; ω] about the origin
    M[:3, :3] = (m_h + m_p) * np.eye(3)
    M[:3, 3:] = -m_p * skew(c_p)
    M[3:, :3] = m_p * skew(c_p)
    M[3:, 3:] = np.diag([5.0, 6.0, 7.0]) + I_p_origin
    r = c_p - hinge
    I_aa = a @ (np.diag([1.0, 0.1, 1.0]) + m_p * (r @ r * np.eye(3) - np.outer(r, r))) @ a
    b = np.concatenate([m_p * np.cross(a, r), I_aa * a + np.cross(hinge, m_p * np.cross(a, r))])
    omega = math.sqrt(k / (I_aa - b @ np.linalg.solve(M, b)))

    sm = compile_path(DATA / "hub_hinge.yaml")
    s = State(sm.q0.copy(), np.zeros(sm.nv), np.zeros(0), np.zeros(0))
    s.q[sm.idx.q_passive[0]] = 1e-4
    dt, crossings, prev, t = 0.005, [], s.q[sm.idx.q_passive[0]], 0.0
    while len(crossings) < 11:
        s = rkmk4_step(sm.model, s, dt, lambda q, v, e, ed: sm.forward_dynamics(q, v, e, ed, np.zeros(sm.nv)))
        t += dt
        x = s.q[sm.idx.q_passive[0]]
        if prev > 0 >= x or prev < 0 <= x:
            crossings.append(t - dt * x / (x - prev))
        prev = x
    period = 2 * (crossings[-1] - crossings[0]) / (len(crossings) - 1)
    assert 2 * math.pi / period == pytest.approx(omega, rel=1e-5)
