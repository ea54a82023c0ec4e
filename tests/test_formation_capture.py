"""Capture through the compliant 6-DoF interface (sms_cli.formation.capture).

Oracles: closed forms (two-mass reduced mass, 1-D oscillator peak force), an independent Λ_rel from the two
bodies' spatial inertias and one from ABA's response to a wrench pair, conservation (world momentum, energy
when undamped, with RK4's 16x error shrink), the power identity, and the interface's measured ringing
frequency. The plant is one Pinocchio model holding both free flyers, stepped by a Runge–Kutta–Munthe-Kaas RK4
written here (exact dexp⁻¹ through ``pin.dIntegrate``, so order 4 on the group for both free flyers).
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest
from scipy.linalg import eigh

from sms_cli.errors import EXIT_INPUT, EXIT_NUMERICAL, InputError, Location, NumericalError
from sms_cli.formation.capture import (
    CaptureMonitor,
    InterfaceGains,
    capture_offset,
    check_capture_offset,
    check_resolution,
    interface_energy,
    interface_wrenches,
    joint_forces,
    relative_jacobian,
    relative_operational_inertia,
    system_momentum,
)

# ---------------------------------------------------------------------------------------------- models


def _rot(rpy) -> np.ndarray:
    return pin.rpy.rpyToMatrix(*rpy)


def _free_body(prefix: str, mass: float, com, inertia, frame: str, frame_pose: pin.SE3) -> pin.Model:
    """A free flyer with one rigid body and one operational frame."""
    model = pin.Model()
    j = model.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), prefix + "_root")
    model.appendBodyToJoint(j, pin.Inertia(mass, np.asarray(com, float), np.asarray(inertia, float)),
                            pin.SE3.Identity())
    model.addFrame(pin.Frame(frame, j, frame_pose, pin.FrameType.OP_FRAME))
    return model


def _servicer_with_arm() -> pin.Model:
    """Servicer base (free flyer) with a 2-joint arm (RZ then RY) and an end-effector frame 'ee'."""
    I_base = np.array([[80.0, 2.0, -1.0], [2.0, 100.0, 3.0], [-1.0, 3.0, 120.0]])
    model = _free_body("srv", 500.0, [0.05, -0.02, 0.01], I_base, "srv_port", pin.SE3.Identity())
    j1 = model.addJoint(1, pin.JointModelRZ(), pin.SE3(np.eye(3), np.array([0.8, 0.0, 0.4])), "srv_j1")
    model.appendBodyToJoint(j1, pin.Inertia(12.0, np.array([0.5, 0.0, 0.0]), np.diag([0.05, 1.0, 1.0])),
                            pin.SE3.Identity())
    j2 = model.addJoint(j1, pin.JointModelRY(), pin.SE3(np.eye(3), np.array([1.0, 0.0, 0.0])), "srv_j2")
    model.appendBodyToJoint(j2, pin.Inertia(8.0, np.array([0.4, 0.0, 0.0]), np.diag([0.03, 0.5, 0.5])),
                            pin.SE3.Identity())
    model.addFrame(pin.Frame("ee", j2, pin.SE3(np.eye(3), np.array([0.8, 0.0, 0.0])), pin.FrameType.OP_FRAME))
    return model


def _client() -> pin.Model:
    I_client = np.array([[40.0, -1.5, 0.5], [-1.5, 55.0, 2.0], [0.5, 2.0, 35.0]])
    grapple = pin.SE3(_rot([0.1, -0.2, 0.3]), np.array([-0.7, 0.1, 0.05]))
    return _free_body("cli", 300.0, [0.02, 0.03, -0.01], I_client, "grapple", grapple)


def _combined(model_a: pin.Model, model_b: pin.Model) -> pin.Model:
    """Both trees in one model, zero gravity (``pin.Model()`` starts with g = −9.81 z)."""
    model = pin.appendModel(model_a, model_b, 0, pin.SE3.Identity())
    model.gravity = pin.Motion.Zero()
    return model


def _set_root(model: pin.Model, q: np.ndarray, root: str, pose: pin.SE3) -> None:
    iq = model.joints[model.getJointId(root)].idx_q
    q[iq:iq + 7] = pin.SE3ToXYZQUAT(pose)


def _set_root_velocity(model: pin.Model, v: np.ndarray, root: str, twist) -> None:
    iv = model.joints[model.getJointId(root)].idx_v
    v[iv:iv + 6] = twist


def _place_b_at(model: pin.Model, data: pin.Data, q: np.ndarray, frame_a: str, frame_b: str, root_b: str,
                g_ab: pin.SE3) -> None:
    """Move body b's root so that g_a⁻¹ g_b = g_ab."""
    pin.framesForwardKinematics(model, data, q)
    fb = model.frames[model.getFrameId(frame_b)]
    assert model.names[fb.parentJoint] == root_b
    _set_root(model, q, root_b, data.oMf[model.getFrameId(frame_a)] * g_ab * fb.placement.inverse())


# ------------------------------------------------------------------------------------------ integrator


def _rkmk4_step(model: pin.Model, q: np.ndarray, v: np.ndarray, dt: float, accel) -> tuple[np.ndarray, np.ndarray]:
    """One RKMK4 step: q(t) = q ⊕ u(t), u̇ = dIntegrate_dv(q, u)⁻¹ v (exact), v̇ = accel(q ⊕ u, v)."""

    def f(u, vv):
        qq = pin.integrate(model, q, u)
        du = np.linalg.solve(pin.dIntegrate(model, q, u, pin.ArgumentPosition.ARG1), vv)
        return du, accel(qq, vv)

    k1u, k1v = f(np.zeros(model.nv), v)
    k2u, k2v = f(0.5 * dt * k1u, v + 0.5 * dt * k1v)
    k3u, k3v = f(0.5 * dt * k2u, v + 0.5 * dt * k2v)
    k4u, k4v = f(dt * k3u, v + dt * k3v)
    u = dt / 6.0 * (k1u + 2 * k2u + 2 * k3u + k4u)
    return pin.integrate(model, q, u), v + dt / 6.0 * (k1v + 2 * k2v + 2 * k3v + k4v)


def _accel(model, data, frame_a, frame_b, target, gains, tau=None):
    """v̇ from ABA with the interface wrenches (gains None: no interface) and joint torques tau(q, v)."""

    def accel(q, v):
        t = np.zeros(model.nv) if tau is None else tau(q, v)
        if gains is None:
            return pin.aba(model, data, q, v, t)
        w = interface_wrenches(model, data, q, v, frame_a, frame_b, target, gains)
        return pin.aba(model, data, q, v, t, joint_forces(model, w))

    return accel


def _energy(model, data, q, v, frame_a, frame_b, target, gains) -> float:
    kinetic = pin.computeKineticEnergy(model, data, q, v)
    return kinetic + interface_energy(model, data, q, frame_a, frame_b, target, gains)


def _momentum_by_bodies(model: pin.Model, data: pin.Data, q, v) -> np.ndarray:
    """Σ over bodies of Ad_{oMi}^{-T} (I_i V_i): [p; L about the world origin], world axes (independent of
    ``system_momentum``)."""
    pin.forwardKinematics(model, data, q, v)
    h = np.zeros(6)
    for i in range(1, model.njoints):
        h += data.oMi[i].act(model.inertias[i] * data.v[i]).vector
    return h


def _two_points(m1: float, m2: float, tip: float) -> tuple[pin.Model, pin.SE3]:
    """Two point-mass-like bodies (rotational inertia 1e-4 m) along world x, frames 'a_tip' (+tip on A) and
    'b_tip' (−tip on B) facing each other; returns the model and the target pose (frames coincident)."""
    model_a = _free_body("A", m1, [0, 0, 0], 1e-4 * m1 * np.eye(3), "a_tip", pin.SE3(np.eye(3), np.array([tip, 0, 0])))
    model_b = _free_body("B", m2, [0, 0, 0], 1e-4 * m2 * np.eye(3), "b_tip", pin.SE3(np.eye(3), np.array([-tip, 0, 0])))
    return _combined(model_a, model_b), pin.SE3.Identity()


def _two_bodies_at_coms() -> pin.Model:
    """Two general rigid bodies with their interface frames at their CoMs (rotated frames)."""
    I_a = np.array([[20.0, 1.0, -0.5], [1.0, 30.0, 2.0], [-0.5, 2.0, 25.0]])
    I_b = np.array([[6.0, -0.3, 0.2], [-0.3, 9.0, 0.4], [0.2, 0.4, 7.5]])
    com_a, com_b = np.array([0.1, -0.2, 0.05]), np.array([-0.05, 0.1, 0.2])
    model_a = _free_body("A", 120.0, com_a, I_a, "a_com", pin.SE3(_rot([0.3, 0.1, -0.2]), com_a))
    model_b = _free_body("B", 45.0, com_b, I_b, "b_com", pin.SE3(_rot([-0.1, 0.4, 0.25]), com_b))
    return _combined(model_a, model_b)


def _arm_stack(q_arm=(0.3, -0.4)) -> tuple[pin.Model, pin.Data, np.ndarray, pin.SE3]:
    """Servicer with arm + client, grapple placed near its target pose relative to the end effector."""
    model = _combined(_servicer_with_arm(), _client())
    data = model.createData()
    q = pin.neutral(model)
    q[7:9] = q_arm
    _set_root(model, q, "srv_root", pin.SE3(_rot([0.2, -0.1, 0.4]), np.array([1.0, -2.0, 0.5])))
    target = pin.SE3(_rot([0.0, 0.0, math.pi]), np.array([0.05, 0.0, 0.0]))
    _place_b_at(model, data, q, "ee", "grapple", "cli_root",
                target * pin.exp6(np.array([0.01, -0.01, 0.005, 0.02, -0.01, 0.015])))
    return model, data, q, target


# ------------------------------------------------------------------------------- relative inertia


@pytest.mark.parametrize("tip", [0.0, 0.5])
def test_two_mass_reduced_mass(tip):
    """Point-mass-like bodies m1, m2 along x: Λ_rel's x translation is m1 m2/(m1+m2), decoupled from the rest;
    with coincident frames at the CoMs the whole translational block is that reduced mass."""
    m1, m2 = 4.0, 6.0
    model, _ = _two_points(m1, m2, tip)
    data = model.createData()
    q = pin.neutral(model)
    _set_root(model, q, "B_root", pin.SE3(np.eye(3), np.array([2 * tip, 0.0, 0.0])))
    lam = relative_operational_inertia(model, data, q, "a_tip", "b_tip")
    mu = m1 * m2 / (m1 + m2)
    assert lam[0, 0] == pytest.approx(mu, rel=1e-12)
    np.testing.assert_allclose(lam[0, 1:], 0.0, rtol=0, atol=1e-12 * mu)
    if tip == 0.0:
        np.testing.assert_allclose(lam[:3, :3], mu * np.eye(3), rtol=0, atol=1e-12 * mu)


def test_relative_inertia_from_spatial_inertias():
    """Two free rigid bodies: Λ_rel⁻¹ = Ad_{b←a} M_a⁻¹ Ad_{b←a}ᵀ + M_b⁻¹, M_i the body's spatial inertia at its
    interface frame (independent of CRBA and the Jacobians); J_rel maps v to V_rel as frame velocities give it."""
    model = _two_bodies_at_coms()
    data = model.createData()
    q = pin.neutral(model)
    _set_root(model, q, "A_root", pin.SE3(_rot([0.5, -0.3, 1.1]), np.array([0.3, 0.2, -0.1])))
    _set_root(model, q, "B_root", pin.SE3(_rot([-0.7, 0.2, 0.4]), np.array([1.5, -0.4, 0.6])))
    lam = relative_operational_inertia(model, data, q, "a_com", "b_com")
    pin.framesForwardKinematics(model, data, q)
    fa, fb = model.getFrameId("a_com"), model.getFrameId("b_com")
    M_a = model.inertias[1].se3Action(model.frames[fa].placement.inverse()).matrix()  # inertia at frame a
    M_b = model.inertias[2].se3Action(model.frames[fb].placement.inverse()).matrix()
    Ad = data.oMf[fb].actInv(data.oMf[fa]).action
    expected = np.linalg.inv(Ad @ np.linalg.solve(M_a, Ad.T) + np.linalg.inv(M_b))
    np.testing.assert_allclose(lam, expected, rtol=0, atol=1e-10 * np.abs(expected).max())

    v = np.random.default_rng(1).normal(size=model.nv)
    J_rel = relative_jacobian(model, data, q, "a_com", "b_com")
    pin.forwardKinematics(model, data, q, v)
    V_a = pin.getFrameVelocity(model, data, fa, pin.LOCAL).vector
    V_b = pin.getFrameVelocity(model, data, fb, pin.LOCAL).vector
    np.testing.assert_allclose(J_rel @ v, V_b - Ad @ V_a, rtol=0, atol=1e-12)


def test_relative_inertia_from_aba_response():
    """With the arm: at rest, the wrench pair (F_b, F_a = −Ad_{b←a}ᵀ F_b) gives V̇_rel = Λ_rel⁻¹ F_b; measured
    column by column through ABA with ``joint_forces`` (no CRBA), and ``joint_forces`` equals Jᵀ F."""
    model, data, q, _ = _arm_stack()
    fa, fb = model.getFrameId("ee"), model.getFrameId("grapple")
    lam = relative_operational_inertia(model, data, q, "ee", "grapple")
    J_rel = relative_jacobian(model, data, q, "ee", "grapple")
    pin.framesForwardKinematics(model, data, q)
    Ad = data.oMf[fb].actInv(data.oMf[fa]).action
    zero = np.zeros(model.nv)
    mobility = np.zeros((6, 6))
    for k in range(6):
        F_b = np.eye(6)[k]
        a = pin.aba(model, data, q, zero, zero, joint_forces(model, [(fa, -Ad.T @ F_b), (fb, F_b)]))
        mobility[:, k] = J_rel @ a  # J̇_rel v = 0 at rest
    np.testing.assert_allclose(lam @ mobility, np.eye(6), rtol=0, atol=1e-9)

    v = np.random.default_rng(2).normal(size=model.nv) * 0.1
    wrenches = [(fa, np.arange(1.0, 7.0)), (fb, np.array([0.5, -2.0, 1.0, 0.3, 0.1, -0.7]))]
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    tau = sum(pin.getFrameJacobian(model, data, f, pin.LOCAL).T @ F for f, F in wrenches)
    np.testing.assert_allclose(pin.aba(model, data, q, v, zero, joint_forces(model, wrenches)),
                               pin.aba(model, data, q, v, tau), rtol=0, atol=1e-10)


def test_same_body_frames_are_refused():
    """Two frames of one rigid body cannot move relative to each other: a NumericalError, not a silent inverse."""
    model = _combined(_client(), _servicer_with_arm())
    data = model.createData()
    model.addFrame(pin.Frame("grapple2", 1, pin.SE3(np.eye(3), np.array([0.3, 0, 0])), pin.FrameType.OP_FRAME))
    data = model.createData()
    with pytest.raises(NumericalError, match="cannot move relative"):
        relative_operational_inertia(model, data, pin.neutral(model), "grapple", "grapple2")
    with pytest.raises(InputError, match="no frame named 'grapel'") as err:
        relative_operational_inertia(model, data, pin.neutral(model), "grapel", "grapple2")
    assert err.value.exit_code == EXIT_INPUT


# ------------------------------------------------------------------------------------------- gains


def test_gains_put_every_mode_at_the_frequency():
    """K x = λ Λ_rel x has λ = ω² six times and D x = μ Λ_rel x has μ = 2ζω (so each mode has ratio ζ)."""
    model, data, q, _ = _arm_stack()
    lam = relative_operational_inertia(model, data, q, "ee", "grapple")
    assert np.all(np.linalg.eigvalsh(lam) > 0)
    f, zeta = 1.7, 0.3
    gains = InterfaceGains.from_frequency(lam, f, zeta)
    w = 2 * math.pi * f
    np.testing.assert_allclose(eigh(gains.K, lam, eigvals_only=True), w * w, rtol=1e-9)
    np.testing.assert_allclose(eigh(gains.D, lam, eigvals_only=True), 2 * zeta * w, rtol=1e-9)
    with pytest.raises(InputError, match="positive"):
        InterfaceGains.from_frequency(lam, 0.0, 0.1)
    with pytest.raises(InputError, match="damping ratio"):
        InterfaceGains.from_frequency(lam, 1.0, -0.1)


def _crossings(t: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Zero-crossing times of x(t) and the slope there, from the cubic through the four samples around each."""
    times, slopes = [], []
    for k in np.nonzero(np.sign(x[:-1]) * np.sign(x[1:]) < 0)[0]:
        if 1 <= k < len(x) - 2:
            p = np.polynomial.Polynomial.fit(t[k - 1:k + 3], x[k - 1:k + 3], 3)
            root = min((r.real for r in p.roots() if abs(r.imag) < 1e-9), key=lambda r: abs(r - t[k]))
            times.append(root)
            slopes.append(p.deriv()(root))
    return np.array(times), np.array(slopes)


@pytest.mark.parametrize("zeta", [0.0, 0.15])
def test_linearised_interface_rings_at_the_frequency(zeta):
    """Two free rigid bodies joined at their CoMs, released at rest 1e-5 from the target pose: each of the six
    error coordinates (relative translation and rotation) crosses zero every T_d/2, T_d = 1/(f √(1−ζ²)), and
    decays by exp(−ζ ω T_d) per period."""
    model = _two_bodies_at_coms()
    data = model.createData()
    q = pin.neutral(model)
    _set_root(model, q, "A_root", pin.SE3(_rot([0.5, -0.3, 1.1]), np.array([0.3, 0.2, -0.1])))
    target = pin.SE3(_rot([0.2, 0.5, -0.3]), np.array([1.2, -0.3, 0.4]))
    e0 = 1e-5 * np.array([1.0, -0.7, 0.5, 0.8, -1.2, 0.6])
    _place_b_at(model, data, q, "a_com", "b_com", "B_root", target * pin.exp6(e0))
    f = 0.5
    w = 2 * math.pi * f
    gains = InterfaceGains.from_frequency(relative_operational_inertia(model, data, q, "a_com", "b_com"), f, zeta)
    accel = _accel(model, data, "a_com", "b_com", target, gains)
    fa, fb = model.getFrameId("a_com"), model.getFrameId("b_com")
    dt, v = 1.0 / f / 200, np.zeros(model.nv)
    ts, es = [], []
    for k in range(int(3.3 * 200)):
        pin.framesForwardKinematics(model, data, q)
        ts.append(k * dt)
        es.append(pin.log6(target.actInv(data.oMf[fa].actInv(data.oMf[fb]))).vector)
        q, v = _rkmk4_step(model, q, v, dt, accel)
    ts, es = np.array(ts), np.array(es)
    T_d = 1.0 / (f * math.sqrt(1 - zeta**2))
    for i in range(6):
        tc, slope = _crossings(ts, es[:, i])
        assert len(tc) >= 6
        half_periods = np.diff(tc)
        np.testing.assert_allclose(half_periods, T_d / 2, rtol=1e-4, err_msg=f"component {i}")
        decay = np.abs(slope[2:] / slope[:-2])
        np.testing.assert_allclose(decay, math.exp(-zeta * w * T_d), rtol=1e-4, err_msg=f"component {i}")


# ------------------------------------------------------------------------------------ conservation


def test_wrench_pair_power_and_momentum_identities():
    """At a random state: the pair's power F_aᵀV_a + F_bᵀV_b equals −dU/dt − V_relᵀ D V_rel (dU/dt by central
    differences along v), and the two wrenches transported to the world cancel."""
    model, data, q, target = _arm_stack()
    v = np.random.default_rng(3).normal(size=model.nv) * 0.2
    lam = relative_operational_inertia(model, data, q, "ee", "grapple")
    gains = InterfaceGains.from_frequency(lam, 1.3, 0.4)
    wrenches = interface_wrenches(model, data, q, v, "ee", "grapple", target, gains)
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    power = sum(F @ (pin.getFrameJacobian(model, data, f, pin.LOCAL) @ v) for f, F in wrenches)
    V_rel = relative_jacobian(model, data, q, "ee", "grapple") @ v
    eps = 1e-6
    U = [interface_energy(model, data, pin.integrate(model, q, s * eps * v), "ee", "grapple", target, gains)
         for s in (1, -1)]
    dU = (U[0] - U[1]) / (2 * eps)
    assert power == pytest.approx(-dU - V_rel @ gains.D @ V_rel, rel=1e-7)
    pin.framesForwardKinematics(model, data, q)
    world = sum(data.oMf[f].act(pin.Force(F)).vector for f, F in wrenches)
    np.testing.assert_allclose(world, 0.0, rtol=0, atol=1e-12 * max(np.abs(F).max() for _, F in wrenches))


def _run_energy(model, data, q, v, target, gains, dt, duration):
    accel = _accel(model, data, "ee", "grapple", target, gains)
    energies = [_energy(model, data, q, v, "ee", "grapple", target, gains)]
    for _ in range(int(round(duration / dt))):
        q, v = _rkmk4_step(model, q, v, dt, accel)
        energies.append(_energy(model, data, q, v, "ee", "grapple", target, gains))
    return np.array(energies)


def _tumbling_arm_stack():
    model, data, q, target = _arm_stack()
    v = np.zeros(model.nv)
    _set_root_velocity(model, v, "srv_root", [0.01, 0.002, -0.005, 0.01, 0.02, -0.015])
    _set_root_velocity(model, v, "cli_root", [-0.02, 0.01, 0.015, 0.04, -0.06, 0.05])
    v[6:8] = [0.05, -0.03]
    return model, data, q, v, target


def test_undamped_interface_conserves_energy_at_the_integrator_order():
    """Kinetic + interface energy of the tumbling stack (free arm joints, undamped 2 Hz interface): its largest
    drift over 1 s shrinks by ≥ 2⁴·0.75 when dt halves (RK4; measured ~32x: on a near-linear oscillator RK4's
    energy error is O(dt⁵)), and it is small against the energy."""
    model, data, q, v, target = _tumbling_arm_stack()
    f = 2.0
    gains = InterfaceGains.from_frequency(relative_operational_inertia(model, data, q, "ee", "grapple"), f, 0.0)
    drift = []
    for n in (40, 80):
        E = _run_energy(model, data, q.copy(), v.copy(), target, gains, 1.0 / f / n, 1.0)
        drift.append(np.abs(E - E[0]).max())
    assert drift[1] < 1e-6 * E[0]
    assert drift[0] / drift[1] >= 12.0, drift


def test_damped_interface_never_adds_energy():
    """With ζ = 0.3 the energy decreases at every step (by far more than the integrator's error)."""
    model, data, q, v, target = _tumbling_arm_stack()
    gains = InterfaceGains.from_frequency(relative_operational_inertia(model, data, q, "ee", "grapple"), 2.0, 0.3)
    E = _run_energy(model, data, q, v, target, gains, 1.0 / 2.0 / 80, 1.5)
    assert np.all(np.diff(E) <= 1e-12 * E[0])
    assert E[-1] < 0.5 * E[0]


def test_momentum_through_a_capture():
    """Servicer with a free (unactuated) arm and a tumbling, approaching client fly free until t_c = 0.5 s, then
    the 1 Hz, ζ = 0.7 interface joins end effector and grapple. World momentum (about the world origin) before =
    after to 1e-9 relative; two independent momentum sums agree."""
    model, data, q, v, target = _tumbling_arm_stack()
    t_c, f, dt = 0.5, 1.0, 1.0 / 400
    free = _accel(model, data, "ee", "grapple", target, None)
    h0 = system_momentum(model, data, q, v)
    scale = np.linalg.norm(h0)
    np.testing.assert_allclose(_momentum_by_bodies(model, data, q, v), h0, rtol=0, atol=1e-13 * scale)
    for _ in range(int(round(t_c / dt))):
        q, v = _rkmk4_step(model, q, v, dt, free)
    monitor = CaptureMonitor(model)
    monitor.at_capture(data, t_c, q, v, "ee", "grapple", target)
    pin.framesForwardKinematics(model, data, q)
    d, a = check_capture_offset(data.oMf[model.getFrameId("ee")], data.oMf[model.getFrameId("grapple")], target,
                                t_c, 0.05, 5.0)
    assert (d, a) == monitor.offset and d > 0.01 and a > 1.0
    gains = InterfaceGains.from_frequency(relative_operational_inertia(model, data, q, "ee", "grapple"), f, 0.7)
    joined = _accel(model, data, "ee", "grapple", target, gains)
    for _ in range(int(round(4.0 / dt))):
        q, v = _rkmk4_step(model, q, v, dt, joined)
        monitor.sample(interface_wrenches(model, data, q, v, "ee", "grapple", target, gains))
    m = monitor.finish(data, q, v)
    np.testing.assert_allclose(m.momentum_before, h0, rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(m.momentum_after, m.momentum_before, rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(_momentum_by_bodies(model, data, q, v), m.momentum_after, rtol=0, atol=1e-13 * scale)
    assert m.peak_force_N > 0 and m.peak_torque_Nm > 0 and m.t_capture == t_c


def test_docked_stack_turns_at_the_locked_rate():
    """Two rigid spacecraft docked port to port (ζ = 0.7, 1 Hz) while tumbling at Ω: 5 s later the relative motion has
    died down to the interface's quasi-static deflection under the spin, (Ω/ω)² ≈ 2e-5 (measured 3e-6), and both
    bodies turn at the stack's locked rate ω_L = I_G⁻¹ L_G to that accuracy, while the CoM moves at p/m:
    ``CaptureMetrics.stack_twist`` (world axes) and ``stack_rate_base`` (servicer base axes)."""
    model = _two_bodies_at_coms()
    data = model.createData()
    q, v = pin.neutral(model), np.zeros(model.nv)
    _set_root(model, q, "A_root", pin.SE3(_rot([0.5, -0.3, 1.1]), np.array([0.3, 0.2, -0.1])))
    target = pin.SE3(_rot([0.2, 0.5, -0.3]), np.array([1.2, -0.3, 0.4]))
    _place_b_at(model, data, q, "a_com", "b_com", "B_root", target * pin.exp6(np.array([0.02, 0, -0.01, 0, 0.03, 0])))
    _set_root_velocity(model, v, "A_root", [0.01, 0.0, 0.02, 0.02, -0.01, 0.03])
    _set_root_velocity(model, v, "B_root", [-0.03, 0.01, 0.0, -0.05, 0.08, 0.02])
    gains = InterfaceGains.from_frequency(relative_operational_inertia(model, data, q, "a_com", "b_com"), 1.0, 0.7)
    V_rel_c = relative_jacobian(model, data, q, "a_com", "b_com") @ v
    monitor = CaptureMonitor(model)
    monitor.at_capture(data, 0.0, q, v, "a_com", "b_com", target)
    accel = _accel(model, data, "a_com", "b_com", target, gains)
    for _ in range(int(round(5.0 * 200))):
        q, v = _rkmk4_step(model, q, v, 1.0 / 200, accel)
        monitor.sample(interface_wrenches(model, data, q, v, "a_com", "b_com", target, gains))
    m = monitor.finish(data, q, v)
    omega = m.stack_twist[3:]
    quasi_static = (np.linalg.norm(omega) / (2 * math.pi * 1.0)) ** 2  # the interface's deflection under the spin
    V_rel = relative_jacobian(model, data, q, "a_com", "b_com") @ v
    assert np.linalg.norm(V_rel) < quasi_static * np.linalg.norm(V_rel_c)
    pin.forwardKinematics(model, data, q, v)
    for j in (1, 2):
        np.testing.assert_allclose(data.oMi[j].rotation @ data.v[j].angular, omega,
                                   rtol=0, atol=quasi_static * np.linalg.norm(omega))
    np.testing.assert_allclose(m.stack_rate_base, v[3:6], rtol=0, atol=quasi_static * np.linalg.norm(omega))
    mass = sum(model.inertias[j].mass for j in (1, 2))
    np.testing.assert_allclose(m.stack_twist[:3], m.momentum_after[:3] / mass, rtol=0, atol=1e-14)
    np.testing.assert_allclose(m.momentum_after, m.momentum_before, rtol=0,
                               atol=1e-9 * np.linalg.norm(m.momentum_before))


def test_peak_force_of_a_head_on_capture():
    """Point-mass-like bodies meeting tip to tip along x at relative speed v0, undamped interface at f: a 1-D
    oscillator of the reduced mass μ, so the peak force is μ ω v0, no torque, and the stack moves at the
    CoM velocity (m1 v1 + m2 v2)/(m1 + m2) without turning."""
    m1, m2, v1, v2, f = 4.0, 6.0, 0.03, -0.02, 2.0
    model, target = _two_points(m1, m2, 0.5)
    data = model.createData()
    q, v = pin.neutral(model), np.zeros(model.nv)
    _set_root(model, q, "B_root", pin.SE3(np.eye(3), np.array([1.0, 0.0, 0.0])))
    _set_root_velocity(model, v, "A_root", [v1, 0, 0, 0, 0, 0])
    _set_root_velocity(model, v, "B_root", [v2, 0, 0, 0, 0, 0])
    gains = InterfaceGains.from_frequency(relative_operational_inertia(model, data, q, "a_tip", "b_tip"), f, 0.0)
    monitor = CaptureMonitor(model)
    monitor.at_capture(data, 0.0, q, v, "a_tip", "b_tip", target)
    accel = _accel(model, data, "a_tip", "b_tip", target, gains)
    dt = 1.0 / f / 400
    for _ in range(400):
        q, v = _rkmk4_step(model, q, v, dt, accel)
        monitor.sample(interface_wrenches(model, data, q, v, "a_tip", "b_tip", target, gains))
    m = monitor.finish(data, q, v)
    mu, w = m1 * m2 / (m1 + m2), 2 * math.pi * f
    assert m.peak_force_N == pytest.approx(mu * w * abs(v2 - v1), rel=1e-4)
    assert m.peak_torque_Nm < 1e-12 * m.peak_force_N
    np.testing.assert_allclose(m.stack_twist, [(m1 * v1 + m2 * v2) / (m1 + m2), 0, 0, 0, 0, 0], rtol=0, atol=1e-14)
    assert (m.offset_m, m.offset_deg) == (0.0, 0.0)


# --------------------------------------------------------------------------------- user-facing checks


def test_check_resolution_needs_twenty_steps_per_period():
    where = Location("missions/capture.yaml", 12, 5)
    f = 12.0
    T = 1.0 / f
    check_resolution(T / 20, f, where)
    with pytest.raises(InputError) as err:
        check_resolution(T / 19, f, where, "simulation.dt")
    assert err.value.exit_code == EXIT_INPUT
    text = err.value.render()
    assert "missions/capture.yaml:12:5" in text and "simulation.dt" in text
    assert "19.0 steps per period" in text and "dt ≤ 0.0041 s" in text
    with pytest.raises(InputError) as err:
        check_resolution(0.01, f, where)
    assert ("plant step 0.01 s resolves the 12 Hz capture interface with 8.3 steps per period; it needs ≥ 20: "
            "set simulation dt ≤ 0.0041 s or lower the interface frequency to ≤ 5 Hz") in err.value.render()
    check_resolution(0.0041, f, where)  # the advised dt is accepted
    for dt, freq in ((0.0, f), (0.01, 0.0), (math.nan, f)):
        with pytest.raises(InputError, match="must be positive"):
            check_resolution(dt, freq, where)


def test_capture_offset_names_the_distance():
    """A grapple placed 0.153 m and 12.1 deg from its target pose: measured exactly; beyond the tolerance a
    NumericalError (exit 3) says how far."""
    g_a = pin.SE3(_rot([0.3, -0.2, 0.9]), np.array([4.0, -1.0, 2.0]))
    target = pin.SE3(_rot([0.0, 0.0, math.pi]), np.array([0.05, 0.0, 0.0]))
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    p = 0.153 * np.array([0.6, 0.0, -0.8])
    g_b = g_a * target * pin.SE3(pin.exp3(math.radians(12.1) * axis), p)
    d, a = capture_offset(g_a, g_b, target)
    assert d == pytest.approx(0.153, rel=1e-12) and a == pytest.approx(12.1, rel=1e-12)
    assert check_capture_offset(g_a, g_b, target, 20.0, 0.2, 15.0) == (d, a)
    with pytest.raises(NumericalError) as err:
        check_capture_offset(g_a, g_b, target, 20.0, 0.05, 5.0)
    assert err.value.exit_code == EXIT_NUMERICAL
    assert ("at the capture time t = 20.0 s the end effector is 0.153 m and 12.1 deg from the grapple fixture; "
            "tolerance 0.05 m / 5 deg") in err.value.render()
    with pytest.raises(NumericalError, match="0.153 m"):
        check_capture_offset(g_a, g_b, target, 20.0, 0.05, 15.0)  # the distance alone
    with pytest.raises(NumericalError, match="12.1 deg"):
        check_capture_offset(g_a, g_b, target, 20.0, 0.2, 5.0)  # the angle alone
