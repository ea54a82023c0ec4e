"""Attitude laws against oracles: closed-form second-order response, Basilisk's documented
mrpFeedback formula evaluated independently, the SMC reaching law's closed-form solution, the
twisting reaching-time bound, the backstepping Lyapunov identity (4.28)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from sms_cli.sim.interfaces import AttitudeRef, Sensed
from sms_cli.sim.laws.attitude import (
    BacksteppingAttitude,
    MrpFeedback,
    QuaternionPD,
    SlidingModeAttitude,
    TrackingError,
    TwistingAttitude,
)
from sms_cli.sim.laws.plant_models import RigidBody


# ----------------------------------------------------------------------------- helpers (independent algebra)
def qmul(a, b):
    """Hamilton product of xyzw quaternions, written from (s1 s2 − v1·v2, s1 v2 + s2 v1 + v1 × v2)."""
    va, sa, vb, sb = np.asarray(a[:3]), a[3], np.asarray(b[:3]), b[3]
    return np.concatenate([sa * vb + sb * va + np.cross(va, vb), [sa * sb - va @ vb]])


def qexp(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    return np.concatenate([math.sin(angle / 2) * axis, [math.cos(angle / 2)]])


def sensed(t, quat, omega, wheel_speed=()):
    return Sensed(t=t, quat=np.asarray(quat, float), omega=np.asarray(omega, float), position=np.zeros(3),
                  velocity=np.zeros(3), q_arm=np.zeros(0), qd_arm=np.zeros(0),
                  wheel_speed=np.asarray(wheel_speed, float), q=np.zeros(7), v=np.zeros(6))


def rigid_rhs(J_of_t, law_torque, ref_of_t, Jdot_of_t=None):
    """d/dt [q (xyzw, base→world), ω (base)] for d(Jω)/dt = τ − ω × Jω, with τ from the law."""
    def f(t, y):
        q, w = y[:4], y[4:7]
        J = J_of_t(t)
        Jd = np.zeros((3, 3)) if Jdot_of_t is None else Jdot_of_t(t)
        tau = law_torque(sensed(t, q, w), ref_of_t(t))
        qd = 0.5 * qmul(q, np.concatenate([w, [0.0]]))
        wd = np.linalg.solve(J, tau - np.cross(w, J @ w) - Jd @ w)
        return np.concatenate([qd, wd])
    return f


def rigid_free(J, Jinv, tau, y):
    """d/dt [q, ω] of a rigid body (constant J) under a held torque: q̇ = ½ q ⊗ (ω, 0)."""
    x, yy, z, s, w1, w2, w3 = y
    h = J @ y[4:7]
    out = np.empty(7)
    out[0] = 0.5 * (s * w1 + yy * w3 - z * w2)
    out[1] = 0.5 * (s * w2 + z * w1 - x * w3)
    out[2] = 0.5 * (s * w3 + x * w2 - yy * w1)
    out[3] = -0.5 * (x * w1 + yy * w2 + z * w3)
    out[4:7] = Jinv @ (tau - np.array([w2 * h[2] - w3 * h[1], w3 * h[0] - w1 * h[2], w1 * h[1] - w2 * h[0]]))
    return out


def zoh_sim(J, law_torque, ref_of_t, y0, T, dt, n_sub=4, disturbance=np.zeros(3)):
    """Control at 1/dt (zero-order hold), fixed-step RK4 sub-steps; yields (t, y, tau) at control instants."""
    y, t, h = np.array(y0, float), 0.0, dt / n_sub
    Jinv = np.linalg.inv(J)
    for _ in range(int(round(T / dt))):
        tau = law_torque(sensed(t, y[:4], y[4:7]), ref_of_t(t))
        yield t, y, tau
        tau = tau + disturbance
        for _ in range(n_sub):
            k1 = rigid_free(J, Jinv, tau, y)
            k2 = rigid_free(J, Jinv, tau, y + 0.5 * h * k1)
            k3 = rigid_free(J, Jinv, tau, y + 0.5 * h * k2)
            k4 = rigid_free(J, Jinv, tau, y + h * k3)
            y = y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
            y[:4] /= np.linalg.norm(y[:4])
        t += dt
    yield t, y, law_torque(sensed(t, y[:4], y[4:7]), ref_of_t(t))


def mrp_to_dcm(s):
    """[BR] from σ_B/R (Schaub & Junkins (3.154)): maps R-frame components to B-frame components."""
    s = np.asarray(s, float)
    S = np.array([[0, -s[2], s[1]], [s[2], 0, -s[0]], [-s[1], s[0], 0]])
    n2 = s @ s
    return np.eye(3) + (8 * S @ S - 4 * (1 - n2) * S) / (1 + n2) ** 2


# ----------------------------------------------------------------------------- conventions
def test_error_kinematics_match_finite_differences():
    """q̇_v = ½(q_w δω + q_v × δω) with δω = ω − Cᵀω_ref, for a moving body and reference."""
    rng = np.random.default_rng(3)
    qb0, qr0 = qexp(rng.normal(size=3), 0.7), qexp(rng.normal(size=3), 1.9)
    w, wr = rng.normal(size=3) * 0.2, rng.normal(size=3) * 0.3

    def at(t):
        qb = qmul(qb0, qexp(w, np.linalg.norm(w) * t))
        qr = qmul(qr0, qexp(wr, np.linalg.norm(wr) * t))
        return TrackingError(sensed(t, qb, w), AttitudeRef(qr, wr, np.zeros(3)))

    h = 1e-6
    fd = (at(h).qv - at(-h).qv) / (2 * h)
    assert np.allclose(fd, at(0.0).qv_dot(), atol=1e-8)
    e = at(0.0)
    assert e.qw >= 0 and abs(np.linalg.norm(e.q) - 1) < 1e-12


# ----------------------------------------------------------------------------- quaternion PD
@pytest.mark.parametrize("axis", [0, 1, 2])
def test_quaternion_pd_small_angle_matches_second_order_closed_form(axis):
    J = np.diag([40.0, 25.0, 10.0])
    I = J[axis, axis]
    kp, kd = 2.0, 6.0
    wn, zeta = math.sqrt(kp / I), kd / (2 * math.sqrt(kp * I))
    assert zeta < 1
    th0 = 1e-3
    law = QuaternionPD(kp, kd)
    e_axis = np.eye(3)[axis]
    ref = AttitudeRef(np.array([0, 0, 0, 1.0]))
    y0 = np.concatenate([qexp(e_axis, th0), np.zeros(3)])
    T = 60.0
    sol = solve_ivp(rigid_rhs(lambda t: J, law.torque, lambda t: ref), (0, T), y0, rtol=1e-11, atol=1e-14,
                    dense_output=True)
    wd = wn * math.sqrt(1 - zeta**2)
    ts = np.linspace(0, T, 200)
    closed = th0 * np.exp(-zeta * wn * ts) * (np.cos(wd * ts) + zeta * wn / wd * np.sin(wd * ts))
    sim = np.array([2 * math.atan2(sol.sol(t)[axis], sol.sol(t)[3]) for t in ts])
    assert np.max(np.abs(sim - closed)) < 1e-6 * th0 * 10  # O(θ²) nonlinearity only
    other = [i for i in range(3) if i != axis]
    assert np.max(np.abs(sol.y[other])) < 1e-12


def test_quaternion_pd_integral_and_feedforward_track_a_rotating_reference():
    """With feedforward and an integral term, a constant disturbance and a spinning reference are
    rejected: the error goes to zero (the integral absorbs the disturbance)."""
    J = np.diag([30.0, 20.0, 12.0])
    law = QuaternionPD([3.0, 2.0, 1.2], [12.0, 8.0, 5.0], ki=[0.3, 0.2, 0.12], feedforward=True, body=RigidBody(J))
    wr = np.array([0.0, 0.0, 0.02])
    d = np.array([0.01, -0.02, 0.005])

    def ref(t):
        return AttitudeRef(qexp([0, 0, 1], 0.02 * t), wr, np.zeros(3))

    *_, (t, y, _) = zoh_sim(J, law.torque, ref, np.concatenate([qexp([1, 1, 0], 0.2), np.zeros(3)]), 200.0, 0.05,
                             n_sub=2, disturbance=d)
    e = TrackingError(sensed(t, y[:4], y[4:7]), ref(t))
    assert e.angle() < 1e-4
    assert np.linalg.norm(e.dw) < 1e-5


# ----------------------------------------------------------------------------- Basilisk mrpFeedback
def basilisk_Lr(K, P, Ki, I, sigma, dw, w_rn_B, dw_rn_B, Gs, Js, Omega, z, law_type, L):
    """The documented formula (mrpFeedback.rst, eq:Lr and the controlLawType paragraph)."""
    w = dw + w_rn_B
    hs = Js * (Gs.T @ w + Omega)
    H = I @ w + Gs @ hs
    v = (w_rn_B + Ki * z) if law_type == 0 else w
    return (-K * sigma - P * dw - P * Ki * z - I @ (-dw_rn_B + np.cross(w, w_rn_B)) - L + np.cross(v, H))


@pytest.mark.parametrize("law_type", [0, 1])
def test_mrp_feedback_equals_basilisk_formula_on_random_inputs(law_type):
    rng = np.random.default_rng(11 + law_type)
    for trial in range(20):
        A = rng.normal(size=(3, 3))
        I = A @ A.T + 5 * np.eye(3)
        Gs = rng.normal(size=(3, 4))
        Gs /= np.linalg.norm(Gs, axis=0)
        Js = rng.uniform(0.05, 0.2, 4)
        K, P, Ki = rng.uniform(0.5, 5), rng.uniform(5, 40), rng.uniform(0.001, 0.01)
        L = rng.normal(size=3) * 0.01
        law = MrpFeedback(K, P, I, Ki=Ki, integral_limit=1e9, control_law_type=law_type, wheel_axes=Gs,
                          wheel_spin=Js, known_torque=L)
        qR = qexp(rng.normal(size=3), rng.uniform(0, 3))
        int_sigma = np.zeros(3)
        prior = 0.0
        for t in (0.0, 0.5, 1.2, 2.0):
            qBR = qexp(rng.normal(size=3), rng.uniform(0, 3.1))
            qB = qmul(qR, qBR)
            wR_R, dwR_R = rng.normal(size=3) * 0.1, rng.normal(size=3) * 0.01
            w = rng.normal(size=3) * 0.1
            Om = rng.normal(size=4) * 100
            out = law.torque(sensed(t, qB, w, Om), AttitudeRef(qR, wR_R, dwR_R))
            # independent evaluation: MRP with shadow set, frames through the MRP DCM
            qe = qBR if qBR[3] >= 0 else -qBR
            sigma = qe[:3] / (1 + qe[3])
            BR = mrp_to_dcm(sigma)
            w_rn_B, dw_rn_B = BR @ wR_R, BR @ dwR_R
            dw = w - w_rn_B
            dt = 0.0 if prior == 0.0 else t - prior
            prior = t
            int_sigma = int_sigma + K * dt * sigma
            z = int_sigma + I @ dw
            ref = basilisk_Lr(K, P, Ki, I, sigma, dw, w_rn_B, dw_rn_B, Gs, Js, Om, z, law_type, L)
            assert np.allclose(out, ref, rtol=1e-10, atol=1e-12), (trial, t)


def test_mrp_feedback_without_integral_and_reference_is_minus_K_sigma_minus_P_omega():
    """The Basilisk reference scenario's law (K = 3.5, P = 30, Ki off, ω_r = 0, type 0)."""
    rng = np.random.default_rng(5)
    I = np.diag([900.0, 800.0, 600.0])
    law = MrpFeedback(3.5, 30.0, I, wheel_axes=np.eye(3), wheel_spin=[0.08, 0.08, 0.08])
    sigma0 = np.array([0.1, 0.2, -0.3])
    q = np.concatenate([2 * sigma0, [1 - sigma0 @ sigma0]]) / (1 + sigma0 @ sigma0)  # quaternion of σ
    w = np.array([0.001, -0.01, 0.03])
    out = law.torque(sensed(0.0, q, w, rng.normal(size=3) * 50), AttitudeRef(np.array([0, 0, 0, 1.0])))
    assert np.allclose(out, -3.5 * sigma0 - 30.0 * w, atol=1e-13)


def test_mrp_feedback_lyapunov_rate_is_minus_P_omega_squared():
    """Ki off, regulation: V = ½ωᵀIω + 2K ln(1 + σᵀσ) has V̇ = −P ωᵀω (mrpFeedback.rst, eq:V_dot4)."""
    I = np.diag([900.0, 800.0, 600.0])
    K, P = 3.5, 30.0
    law = MrpFeedback(K, P, I, control_law_type=1)
    ref = AttitudeRef(np.array([0, 0, 0, 1.0]))
    y0 = np.concatenate([qexp([1, 2, -3], 1.0), [0.001, -0.01, 0.03]])
    sol = solve_ivp(rigid_rhs(lambda t: I, law.torque, lambda t: ref), (0, 200), y0, rtol=1e-11, atol=1e-13,
                    dense_output=True)

    def V(t):
        y = sol.sol(t)
        sig = TrackingError(sensed(t, y[:4], y[4:7]), ref).mrp()
        return 0.5 * y[4:7] @ I @ y[4:7] + 2 * K * math.log(1 + sig @ sig)

    h = 1e-3
    for t in np.linspace(1, 190, 12):
        dV = (V(t + h) - V(t - h)) / (2 * h)
        w = sol.sol(t)[4:7]
        assert dV == pytest.approx(-P * w @ w, rel=1e-5, abs=1e-12)


# ----------------------------------------------------------------------------- Caldera 2019 SMC
def test_smc_surface_follows_the_closed_form_reaching_law():
    """Exact model: each s_i obeys ṡ = −c tanh(μ s), so sinh(μ s(t)) = sinh(μ s(0)) e^{−cμt}."""
    J = np.array([[50.0, 1.0, -0.5], [1.0, 25.0, 0.3], [-0.5, 0.3, 25.0]])
    k, c, mu = 0.1, 0.01, 10.0
    law = SlidingModeAttitude(k, c, mu, RigidBody(J))
    qref = np.array([0.15849365, 0.59150635, 0.15849365, 0.77451905])  # Z-Y-X [π/3]³ (Caldera 2019 S1)
    wr = np.array([0.0, 0.01, 0.0])

    def ref(t):
        return AttitudeRef(qmul(qref, qexp([0, 1, 0], 0.01 * t)), wr, np.zeros(3))

    y0 = np.concatenate([[0, 0, 0, 1.0], [0.02, -0.01, 0.005]])
    sol = solve_ivp(rigid_rhs(lambda t: J, law.torque, ref), (0, 150), y0, rtol=1e-11, atol=1e-13, dense_output=True)
    s0 = law.surface(sensed(0, y0[:4], y0[4:7]), ref(0))
    for t in (5.0, 20.0, 60.0, 150.0):
        y = sol.sol(t)
        s = law.surface(sensed(t, y[:4], y[4:7]), ref(t))
        closed = np.arcsinh(np.sinh(mu * s0) * math.exp(-c * mu * t)) / mu
        assert np.allclose(s, closed, atol=1e-8)
    y = sol.sol(150.0)
    assert TrackingError(sensed(150, y[:4], y[4:7]), ref(150)).angle() < math.radians(0.2)


def test_smc_printed_signs_of_seed_000_diverge():
    """(3.16)–(3.17) as printed (−½k(…), −cI tanh) with q_e = q⁻¹∘q_r, ω_e = ω_r − ω: no convergence."""
    J = np.diag([50.0, 25.0, 25.0])
    k, c, mu = 0.1, 0.01, 10.0
    qref = np.array([0.15849365, 0.59150635, 0.15849365, 0.77451905])

    def printed(s, ref):
        e = TrackingError(s, ref)
        qe0, qe = e.qw, -e.qv  # seed q_e = q⁻¹ ∘ q_r is the conjugate of ours
        we = -np.asarray(s.omega)
        w = np.asarray(s.omega)
        eq = -0.5 * k * (qe0 * we + np.cross(qe, w))
        ss = we + k * qe
        return J @ eq + np.cross(w, J @ w) - c * J @ np.tanh(mu * ss)

    ref = AttitudeRef(qref)
    y0 = np.array([0, 0, 0, 1.0, 0, 0, 0])
    for law in (printed, SlidingModeAttitude(k, c, mu, RigidBody(J)).torque):
        *_, (t, y, _) = zoh_sim(J, law, lambda t: ref, y0, 240.0, 0.05)
        final = TrackingError(sensed(t, y[:4], y[4:7]), ref).angle()
        if law is printed:
            assert final > math.radians(30)
        else:
            assert final < math.radians(0.5)


# ----------------------------------------------------------------------------- Ruggiero 2020 twisting
def test_twisting_reaches_the_surface_within_its_time_bound_and_stays_bounded():
    J = np.diag([0.153, 0.143, 0.162])  # Astrobee (nasa/astrobee iss.config)
    k1, k2, lam = 0.05, 0.02, 0.5
    law = TwistingAttitude(k1, k2, lam, smoothing="sign")
    ref = AttitudeRef(qexp([0, 0, 1], 0.3))
    dt = 1e-3
    y0 = np.concatenate([[0, 0, 0, 1.0], [0.01, -0.02, 0.0]])
    sig0 = law.surface(sensed(0, y0[:4], y0[4:7]), ref)
    hist, umax, A, qs = [], 0.0, 0.0, []
    for t, y, u in zoh_sim(J, law.torque, lambda t: ref, y0, 20.0, dt, n_sub=1):
        s = sensed(t, y[:4], y[4:7])
        if abs(t - 2.0) < dt / 2 or abs(t - 10.0) < dt / 2:
            qs.append((2.0 if t < 5 else 10.0, y.copy()))
        umax = max(umax, float(np.max(np.abs(u))))
        e = TrackingError(s, ref)
        a = lam * e.qv_dot() - np.linalg.solve(J, np.cross(y[4:7], J @ y[4:7]))  # σ̇ with u = 0
        A = max(A, float(np.max(np.abs(a))))
        hist.append((t, law.surface(s, ref)))
    assert umax <= k1 + k2 + 1e-15
    band = 2 * (k1 + k2) / np.diag(J).min() * dt * 2  # a few control steps of chattering
    bound = np.abs(sig0) / ((k1 - k2) / np.diag(J).max() - A)
    for i in range(3):
        t_reach = next(tt for tt, sg in hist if abs(sg[i]) < band)
        assert t_reach <= bound[i] + 2 * dt
    late = np.array([sg for tt, sg in hist if tt > bound.max() + 0.5])
    assert np.max(np.abs(late)) < band
    # on σ = 0: q̇_v = −½ λ q_w q_v, so |q_v| decays at ≈ λ/2 (q_w ≈ 1 here)
    qv = {round(tt, 6): np.linalg.norm(TrackingError(sensed(tt, yy[:4], yy[4:7]), ref).qv) for tt, yy in qs}
    assert qv[10.0] / qv[2.0] == pytest.approx(math.exp(-0.5 * lam * 8.0), rel=0.03)


# ----------------------------------------------------------------------------- Ruggiero 2020 backstepping
class VaryingBody:
    """J(t) = J0 + sin(0.3 t) ΔJ, the thesis's configuration-dependent inertia, as a body model."""

    def __init__(self):
        self.J0 = np.diag([0.16, 0.15, 0.17])
        self.dJ = np.array([[0.02, 0.003, 0.0], [0.003, 0.01, -0.002], [0.0, -0.002, 0.015]])

    def J(self, t):
        return self.J0 + math.sin(0.3 * t) * self.dJ

    def Jd(self, t):
        return 0.3 * math.cos(0.3 * t) * self.dJ

    def inertia(self, s):
        return self.J(s.t)

    def inertia_rate(self, s):
        return self.Jd(s.t)

    def internal_momentum(self, s):
        return np.zeros(3)


def test_backstepping_lyapunov_rate_equals_minus_K1_minus_K2_terms():
    body = VaryingBody()
    K1, K2 = np.array([0.4, 0.5, 0.3]), np.array([0.2, 0.25, 0.3])
    law = BacksteppingAttitude(K1, K2, body, disturbance="none")
    a1, a2 = np.array([0, 0, 1.0]), np.array([1.0, 0.5, 0.0]) / math.hypot(1, 0.5)
    p1 = (lambda t: 0.05 * t, lambda t: 0.05, lambda t: 0.0)
    p2 = (lambda t: 0.2 * math.sin(0.2 * t), lambda t: 0.04 * math.cos(0.2 * t), lambda t: -0.008 * math.sin(0.2 * t))

    def ref(t):
        q2 = qexp(a2, p2[0](t)) if p2[0](t) != 0 else np.array([0, 0, 0, 1.0])
        R2 = np.eye(3) if p2[0](t) == 0 else _rot(a2, p2[0](t))
        w2 = a2 * p2[1](t)
        wr = R2.T @ a1 * p1[1](t) + w2
        dwr = R2.T @ a1 * p1[2](t) - np.cross(w2, R2.T @ a1 * p1[1](t)) + a2 * p2[2](t)
        return AttitudeRef(qmul(qexp(a1, p1[0](t)) if p1[0](t) else np.array([0, 0, 0, 1.0]), q2), wr, dwr)

    y0 = np.concatenate([qexp([1, -1, 0.5], 1.5), [0.02, 0.0, -0.03]])
    sol = solve_ivp(rigid_rhs(body.J, law.torque, ref, body.Jd), (0, 60), y0, rtol=1e-11, atol=1e-13,
                    dense_output=True)

    def V(t):
        y = sol.sol(t)
        return law.lyapunov(sensed(t, y[:4], y[4:7]), ref(t))

    h = 1e-4
    vals = [V(t) for t in np.linspace(0, 60, 300)]
    assert all(b <= a + 1e-12 for a, b in zip(vals, vals[1:]))
    assert vals[-1] < 1e-3 * vals[0]
    for t in np.linspace(0.5, 55, 15):
        y = sol.sol(t)
        s = sensed(t, y[:4], y[4:7])
        e = TrackingError(s, ref(t))
        wt = y[4:7] - (-K1 * e.qv + e.omega_r)
        expected = -(e.qv @ (K1 * e.qv)) - wt @ (K2 * wt)
        assert (V(t + h) - V(t - h)) / (2 * h) == pytest.approx(expected, rel=1e-5, abs=1e-12)


def _rot(axis, angle):
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    S = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(angle) * S + (1 - math.cos(angle)) * S @ S


def test_backstepping_slews_180_degrees_faster_than_twisting_on_the_same_body():
    """Ruggiero 2020's ranking (L996-1004, R4/G3): backstepping reaches the target before twisting
    (near-180° yaw slew, Astrobee inertia, comparable peak torques)."""
    J = np.diag([0.153, 0.143, 0.162])
    ref = AttitudeRef(qexp([0, 0, 1], math.radians(179)))
    bs = BacksteppingAttitude(0.5, 0.3, RigidBody(J))
    tw = TwistingAttitude(0.04, 0.015, 0.5, eta=1.0)

    def settle(law):
        last_out, peak = 0.0, 0.0
        for t, y, u in zoh_sim(J, law.torque, lambda t: ref, [0, 0, 0, 1.0, 0, 0, 0], 120.0, 0.05):
            peak = max(peak, float(np.max(np.abs(u))))
            if TrackingError(sensed(t, y[:4], y[4:7]), ref).angle() > math.radians(1):
                last_out = t
        return last_out, peak

    t_bs, peak_bs = settle(bs)
    t_tw, peak_tw = settle(tw)
    assert t_bs < t_tw < 120
    assert peak_tw <= 0.04 + 0.015 + 1e-12


# ----------------------------------------------------------------------------- specs and factories
def test_factories_build_every_attitude_law_with_units_and_report_errors():
    from pydantic import TypeAdapter, ValidationError

    from conftest import DATA, compile_path
    from sms_cli.errors import InputError
    from sms_cli.sim.laws import AttitudeLawSpec, build_attitude_law

    sm = compile_path(DATA / "arm3.yaml")
    ta = TypeAdapter(AttitudeLawSpec)
    specs = [
        {"law": "quaternion_pd", "kp": "0.5 N m/rad", "kd": [5, 5, "5 N m s/rad"], "ki": 0, "feedforward": True},
        {"law": "mrp_feedback", "K": 3.5, "P": 30.0},
        {"law": "smc", "k": 0.08, "c": "0.01 rad/s^2", "boundary": "0.05 rad/s", "inertia": [50, 25, 25]},
        {"law": "twisting_smc", "k1": "0.05 N m", "k2": 0.02, "lambda": 0.5, "eta": 10},
        {"law": "backstepping", "K1": 0.5, "K2": 0.3, "inertia": "online"},
    ]
    q = sm.q0.copy()
    s = Sensed(t=0.0, quat=q[3:7], omega=np.array([0.01, 0.0, -0.02]), position=q[:3], velocity=np.zeros(3),
               q_arm=q[sm.idx.q_arm], qd_arm=np.zeros(3), wheel_speed=np.full(4, 10.0), q=q,
               v=np.concatenate([np.zeros(3), [0.01, 0.0, -0.02], np.zeros(3), np.full(4, 10.0)]))
    ref = AttitudeRef(np.array([0, 0, 0, 1.0]))
    for d in specs:
        law = build_attitude_law(ta.validate_python(d), sm)
        tau = law.torque(s, ref)
        assert tau.shape == (3,) and np.all(np.isfinite(tau))
    smc = build_attitude_law(ta.validate_python(specs[2]), sm)
    assert np.allclose(smc.mu, 20.0) and np.allclose(smc.body.J, np.diag([50, 25, 25]))
    with pytest.raises(InputError, match="k1 > k2"):
        build_attitude_law(ta.validate_python({"law": "twisting_smc", "k1": 0.01, "k2": 0.02, "lambda": 1}), sm)
    with pytest.raises(InputError, match="constant inertia"):
        build_attitude_law(ta.validate_python({"law": "mrp_feedback", "K": 1, "P": 1, "inertia": "online"}), sm)
    with pytest.raises(InputError, match="one value or 3 values"):
        build_attitude_law(ta.validate_python({"law": "quaternion_pd", "kp": [1, 2], "kd": 1}), sm)
    with pytest.raises(ValidationError, match="rotational stiffness"):
        ta.validate_python({"law": "quaternion_pd", "kp": "3 m", "kd": 1})
    with pytest.raises(ValidationError, match="exactly one of 'mu'"):
        ta.validate_python({"law": "smc", "k": 0.1, "c": 0.01})


# ----------------------------------------------------------------------------- the kernels against the formulas
# The laws are computed by numba kernels (sms_cli.sim.compiled.attitude_laws), the same in both loops. Here
# each is evaluated independently from its formula (thesis / class docstring), on random states, gains
# (scalar, per-axis, 3×3), moving references, wheel momenta and, for the laws with memory, several calls.
def _oracle_error(qB, qR, w, wR_R, dwR_R):
    """(q_v, q_w, δω, ω_r = Cᵀω_R, Cᵀω̇_R, q̇_v) of q_e = q_R⁻¹ ⊗ q_B (w ≥ 0), C = R(q_e) base → reference
    (scipy); the base-frame derivative of ω_r is Cᵀω̇_R − ω × ω_r (the laws' ω̇_r − ω × ω_r)."""
    from scipy.spatial.transform import Rotation

    conj = np.array([-qR[0], -qR[1], -qR[2], qR[3]])
    qe = qmul(conj, qB)
    qe = qe / np.linalg.norm(qe)
    qe = qe if qe[3] >= 0 else -qe
    C = Rotation.from_quat(qe).as_matrix()
    wr = C.T @ wR_R
    dwr = C.T @ dwR_R
    dw = w - wr
    qv, qw = qe[:3], qe[3]
    return qv, qw, dw, wr, dwr, 0.5 * (qw * dw + np.cross(qv, dw))


def _random_gain(rng, kind, lo, hi):
    if kind == "scalar":
        return float(rng.uniform(lo, hi))
    if kind == "axes":
        return rng.uniform(lo, hi, 3)
    A = rng.normal(size=(3, 3)) * 0.3 * (hi - lo)
    return A @ A.T + lo * np.eye(3)


def _as_matrix(g):
    g = np.asarray(g, float)
    return g if g.ndim == 2 else np.diag(np.broadcast_to(g, (3,)))


class _WheelBody(RigidBody):
    """A rigid body with wheels and a given J̇ (the backstepping's J̇ term)."""

    def __init__(self, J, G, Js, Jd):
        super().__init__(J, G, Js)
        self.Jd = Jd

    def inertia_rate(self, s):
        return self.Jd


def _random_case(rng):
    A = rng.normal(size=(3, 3))
    J = A @ A.T + 2 * np.eye(3)
    G = rng.normal(size=(3, 4))
    G /= np.linalg.norm(G, axis=0)
    Js = rng.uniform(0.05, 0.2, 4)
    B = rng.normal(size=(3, 3)) * 0.05
    return _WheelBody(J, G, Js, B + B.T), G, Js


def _calls(rng, n=5):
    """Random (t, q_B, q_R, ω, ω_R, ω̇_R, Ω) per call; the time steps include a repeated instant."""
    t = 0.0
    out = []
    for k in range(n):
        qB, qR = qexp(rng.normal(size=3), rng.uniform(0, 3.1)), qexp(rng.normal(size=3), rng.uniform(0, 3.1))
        moving = k % 2 == 1
        out.append((t, qB, qR, rng.normal(size=3) * 0.1, rng.normal(size=3) * 0.05 if moving else np.zeros(3),
                    rng.normal(size=3) * 0.01 if moving else np.zeros(3), rng.normal(size=4) * 50))
        t += 0.0 if k == 2 else float(rng.uniform(0.05, 0.4))
    return out


def _close(out, ref):
    assert np.abs(out - ref).max() <= 1e-12 * max(1.0, np.abs(ref).max()), (out, ref)


KINDS = ["scalar", "axes", "matrix"]


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("feedforward", [False, True])
def test_quaternion_pd_kernel_equals_its_formula(kind, feedforward):
    """τ = −k_p θ_e − k_d δω − k_i ∫θ_e dt + [ω×(Jω + h) + J(ω̇_r − ω×ω_r)], θ_e = 2 q_v; the integral
    advanced by θ_e·Δt (Δt = 0 on the first call and at a repeated instant), each component clipped."""
    rng = np.random.default_rng(21 + KINDS.index(kind) + 5 * feedforward)
    for trial in range(4):
        body, G, Js = _random_case(rng)
        kp, kd, ki = (_random_gain(rng, kind, 0.5, 3.0), _random_gain(rng, kind, 1.0, 6.0),
                      _random_gain(rng, kind, 0.1, 0.5))
        lim = 0.05
        law = QuaternionPD(kp, kd, ki, lim, feedforward, body)
        integral, prev = np.zeros(3), None
        for t, qB, qR, w, wR, dwR, Om in _calls(rng):
            out = law.torque(sensed(t, qB, w, Om), AttitudeRef(qR, wR, dwR))
            qv, qw, dw, wr, dwr, _ = _oracle_error(qB, qR, w, wR, dwR)
            theta = 2 * qv
            dt = 0.0 if prev is None else t - prev
            prev = t
            integral = np.clip(integral + theta * dt, -lim, lim)
            ref = -_as_matrix(kp) @ theta - _as_matrix(kd) @ dw - _as_matrix(ki) @ integral
            if feedforward:
                h = G @ (Js * (G.T @ w + Om))
                ref = ref + np.cross(w, body.J @ w + h) + body.J @ (dwr - np.cross(w, wr))
            _close(out, ref)
        assert np.abs(law.integral).max() <= lim and np.allclose(law.integral, integral, rtol=0, atol=1e-15)


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("smoothing, momentum", [("tanh", True), ("sign", True), ("tanh", False)])
def test_smc_kernel_equals_its_formula(kind, smoothing, momentum):
    """s = δω + k q_v, τ = ω×(Jω + h) + J(ω̇_r − ω×ω_r − k q̇_v − c tanh(μ s)) (sign(s)); h = 0 without momentum."""
    rng = np.random.default_rng(41 + KINDS.index(kind) + 3 * (smoothing == "sign") + 7 * momentum)
    for trial in range(4):
        body, G, Js = _random_case(rng)
        k, c, mu = (_random_gain(rng, kind, 0.05, 0.3), _random_gain(rng, kind, 0.005, 0.02),
                    _random_gain(rng, kind, 5.0, 20.0))
        law = SlidingModeAttitude(k, c, mu, body, smoothing, momentum)
        for t, qB, qR, w, wR, dwR, Om in _calls(rng):
            s, ref_att = sensed(t, qB, w, Om), AttitudeRef(qR, wR, dwR)
            out = law.torque(s, ref_att)
            qv, qw, dw, wr, dwr, qvd = _oracle_error(qB, qR, w, wR, dwR)
            surf = dw + _as_matrix(k) @ qv
            sw = np.tanh(_as_matrix(mu) @ surf) if smoothing == "tanh" else np.sign(surf)
            h = G @ (Js * (G.T @ w + Om)) if momentum else np.zeros(3)
            J = body.J
            ref = np.cross(w, J @ w + h) + J @ (dwr - np.cross(w, wr) - _as_matrix(k) @ qvd - _as_matrix(c) @ sw)
            _close(out, ref)
            _close(law.surface(s, ref_att), surf)


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("smoothing, filter_time", [("tanh", 0.0), ("tanh", 0.3), ("sign", 0.2)])
def test_twisting_kernel_equals_its_formula(kind, smoothing, filter_time):
    """σ = λ q_v + δω, u = −k₁ tanh(η σ) − k₂ tanh(η σ̇) (sign); σ̇ the backward difference of σ through
    the filter σ̇ += Δt/(T_f + Δt)·(raw − σ̇), 0 on the first call, kept at a repeated instant."""
    rng = np.random.default_rng(61 + KINDS.index(kind) + 3 * (smoothing == "sign") + int(10 * filter_time))
    for trial in range(4):
        k1, k2, lam, eta = (_random_gain(rng, kind, 0.05, 0.1), _random_gain(rng, kind, 0.01, 0.04),
                            _random_gain(rng, kind, 0.2, 1.0), _random_gain(rng, kind, 1.0, 20.0))
        law = TwistingAttitude(k1, k2, lam, eta, smoothing, filter_time)
        prev_t, prev_sig, sd = None, None, np.zeros(3)
        for t, qB, qR, w, wR, dwR, Om in _calls(rng):
            s, ref_att = sensed(t, qB, w, Om), AttitudeRef(qR, wR, dwR)
            out = law.torque(s, ref_att)
            qv, qw, dw, wr, dwr, _ = _oracle_error(qB, qR, w, wR, dwR)
            sig = _as_matrix(lam) @ qv + dw
            if prev_t is not None and t - prev_t > 0:
                dt = t - prev_t
                sd = sd + dt / (filter_time + dt) * ((sig - prev_sig) / dt - sd)
            prev_t, prev_sig = t, sig
            sw = (lambda x: np.tanh(_as_matrix(eta) @ x)) if smoothing == "tanh" else np.sign
            ref = -_as_matrix(k1) @ sw(sig) - _as_matrix(k2) @ sw(sd)
            _close(out, ref)
            _close(law.sigma_dot, sd)
            _close(law.surface(s, ref_att), sig)


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("disturbance", ["gyroscopic", "none"])
def test_backstepping_kernel_equals_its_formula(kind, disturbance):
    """Ruggiero 2020 (4.15)–(4.27): ω_c = −K₁q_v + ω_r, ω̇_c = −K₁q̇_v + ω̇_r − ω×ω_r, γ = (Jω_c)×ω_c − Jω̇_c − J̇ω_c,
    u = −K₂ω̃ − q_v − T̂_dis − γ + ω_c×(Jω̃) + ½J̇ω̃, T̂_dis = −ω×h (or 0); V₂ = q_vᵀq_v + (1 − q_w)² + ½ω̃ᵀJω̃."""
    rng = np.random.default_rng(81 + KINDS.index(kind) + 3 * (disturbance == "none"))
    for trial in range(4):
        body, G, Js = _random_case(rng)
        K1, K2 = _random_gain(rng, kind, 0.2, 1.0), _random_gain(rng, kind, 0.1, 0.5)
        law = BacksteppingAttitude(K1, K2, body, disturbance)
        for t, qB, qR, w, wR, dwR, Om in _calls(rng):
            s, ref_att = sensed(t, qB, w, Om), AttitudeRef(qR, wR, dwR)
            out = law.torque(s, ref_att)
            qv, qw, dw, wr, dwr, qvd = _oracle_error(qB, qR, w, wR, dwR)
            J, Jd = body.J, body.Jd
            wc = -_as_matrix(K1) @ qv + wr
            wcd = -_as_matrix(K1) @ qvd + dwr - np.cross(w, wr)
            wt = w - wc
            gamma = np.cross(J @ wc, wc) - J @ wcd - Jd @ wc
            h = G @ (Js * (G.T @ w + Om))
            T_dis = -np.cross(w, h) if disturbance == "gyroscopic" else np.zeros(3)
            ref = -_as_matrix(K2) @ wt - qv - T_dis - gamma + np.cross(wc, J @ wt) + 0.5 * Jd @ wt
            _close(out, ref)
            V = qv @ qv + (1 - qw) ** 2 + 0.5 * wt @ J @ wt
            assert law.lyapunov(s, ref_att) == pytest.approx(V, rel=1e-12, abs=1e-15)
