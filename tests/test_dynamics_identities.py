"""Oracles for the SystemModel: algebraic identities of rigid-body dynamics, conservation,
the generalized Jacobian against a free-floating simulation, the seed-convention adapter."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from conftest import DATA, compile_path
from sms_cli.dynamics.integrator import State, rkmk4_step
from sms_cli.model.conventions import base_velocity_from_seed, base_velocity_to_seed, seed_map

LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


@pytest.fixture(scope="module")
def sm():
    return compile_path(DATA / "arm3.yaml")


@pytest.fixture(scope="module")
def rigid(tmp_path_factory):
    d = tmp_path_factory.mktemp("rigid")
    text = (DATA / "arm3.yaml").read_text()
    start, end = text.index("appendages:"), text.index("payloads:")
    (d / "m.yaml").write_text(text[:start] + text[end:])
    (d / "arm3.urdf").write_text((DATA / "arm3.urdf").read_text())
    return compile_path(d / "m.yaml")


def random_state(sm, seed=0):
    rng = np.random.default_rng(seed)
    q = pin.randomConfiguration(sm.model, -np.ones(sm.nq), np.ones(sm.nq))
    q[3:7] = pin.Quaternion(pin.SE3.Random().rotation).coeffs()
    return q, rng.normal(size=sm.nv), rng.normal(size=sm.n_modes) * 0.1, rng.normal(size=sm.n_modes), rng.normal(size=sm.nv)


def modal_inverse_dynamics(sm, q, v, eta, etadot, vdot, etaddot):
    """Independent path: Pinocchio RNEA for the rigid part + the modal coupling terms."""
    m, d = sm.model, sm.data
    tau = pin.rnea(m, d, q, v, vdot).copy()
    res_eta = etaddot + np.concatenate([a.omega for a in sm.appendages]) ** 2 * eta \
        + 2 * np.concatenate([a.zeta * a.omega for a in sm.appendages]) * etadot
    pin.forwardKinematics(m, d, q, v, vdot)
    pin.computeJointJacobians(m, d, q)
    pin.updateFramePlacements(m, d)
    for a in sm.appendages:
        J = pin.getFrameJacobian(m, d, a.frame_id, pin.ReferenceFrame.LOCAL)
        V = pin.getFrameVelocity(m, d, a.frame_id, pin.ReferenceFrame.LOCAL)
        A = pin.getFrameAcceleration(m, d, a.frame_id, pin.ReferenceFrame.LOCAL)  # d/dt of V (with vdot)
        tau += J.T @ (a.L.T @ etaddot[a.modes] + V.cross(pin.Force(a.L.T @ etadot[a.modes])).vector)
        res_eta[a.modes] += a.L @ A.vector
    return tau, res_eta


def test_aba_equals_crba_solve_and_rnea_inverts_it(rigid):
    for seed in range(5):
        q, v, _, _, tau = random_state(rigid, seed)
        a_aba = pin.aba(rigid.model, rigid.data, q, v, tau)
        H = rigid.rigid_mass_matrix(q)
        h = pin.nonLinearEffects(rigid.model, rigid.data, q, v)
        a_crba = np.linalg.solve(H, tau - h)
        assert np.max(np.abs(a_aba - a_crba)) <= 1e-10 * max(1, np.max(np.abs(a_aba)))
        vdot, _ = rigid.forward_dynamics(q, v, np.zeros(0), np.zeros(0), tau)
        assert np.max(np.abs(pin.rnea(rigid.model, rigid.data, q, v, vdot) - tau)) <= 1e-10


def test_forward_dynamics_with_modes_inverted_by_rnea(sm):
    for seed in range(5):
        q, v, eta, etadot, tau = random_state(sm, seed)
        vdot, etaddot = sm.forward_dynamics(q, v, eta, etadot, tau)
        tau_back, res_eta = modal_inverse_dynamics(sm, q, v, eta, etadot, vdot, etaddot)
        assert np.max(np.abs(tau_back - tau)) <= 1e-10
        assert np.max(np.abs(res_eta)) <= 1e-10


def _zero_momentum_state(sm, qdot_arm):
    """Base velocity that makes total momentum zero for given joint rates (wheels at rest)."""
    v = np.zeros(sm.nv)
    v[sm.idx.arm] = qdot_arm
    H = sm.rigid_mass_matrix(sm.q0)
    v[:6] = -np.linalg.solve(H[:6, :6], H[:6, 6:] @ v[6:])
    return v


def _joint_torque(sm, t):
    tau = np.zeros(sm.nv)
    tau[sm.idx.arm] = [2.0 * np.sin(2 * t), -1.5 * np.cos(t), 1.0 * np.sin(3 * t)]
    tau[sm.idx.wheels] = 0.01 * np.cos(t)
    return tau


def _simulate(sm, v0, T, dt, etadot0=None):
    s = State(sm.q0.copy(), v0.copy(), np.zeros(sm.n_modes), np.zeros(sm.n_modes) if etadot0 is None else etadot0.copy())
    out = [s]
    for k in range(int(round(T / dt))):
        tau = _joint_torque(sm, k * dt)
        s = rkmk4_step(sm.model, s, dt, lambda q, v, e, ed: sm.forward_dynamics(q, v, e, ed, tau))
        out.append(s)
    return out


def test_arm_motion_at_zero_momentum_leaves_com_still(rigid):
    v0 = _zero_momentum_state(rigid, [0.2, -0.1, 0.3])
    p, k = rigid.momentum(rigid.q0, v0)
    assert np.linalg.norm(p) < 1e-12 and np.linalg.norm(k) < 1e-12
    c0 = rigid.com(rigid.q0)
    traj = _simulate(rigid, v0, T=2.0, dt=0.0025)
    moved = [np.linalg.norm(rigid.q0[:3] - s.q[:3]) for s in traj]
    assert max(moved) > 1e-3  # the base does move
    assert max(np.linalg.norm(rigid.com(s.q) - c0) for s in traj) < 1e-10


@pytest.mark.parametrize("which", ["rigid", "sm"])
def test_momentum_conserved_by_forward_dynamics(which, request):
    sys_ = request.getfixturevalue(which)
    rng = np.random.default_rng(3)
    v0 = rng.normal(size=sys_.nv) * 0.2
    ed0 = rng.normal(size=sys_.n_modes) * 0.1
    # instantaneous: d/dt (p, k_O) = 0 along the flow (central difference)
    q = sys_.q0
    tau = _joint_torque(sys_, 0.3)
    a, b = sys_.forward_dynamics(q, v0, np.zeros(sys_.n_modes), ed0, tau)

    def h(s):
        return np.concatenate(sys_.momentum(pin.integrate(sys_.model, q, s * v0), v0 + s * a, ed0 + s * b, about="origin"))

    eps = 1e-6
    assert np.max(np.abs((h(eps) - h(-eps)) / (2 * eps))) < 1e-7 * np.max(np.abs(h(0)))
    # over a short explicit integration
    traj = _simulate(sys_, v0, T=1.0, dt=0.005, etadot0=ed0)
    h0 = np.concatenate(sys_.momentum(traj[0].q, traj[0].v, traj[0].etadot, about="origin"))
    h1 = np.concatenate(sys_.momentum(traj[-1].q, traj[-1].v, traj[-1].etadot, about="origin"))
    assert np.max(np.abs(h1 - h0)) <= 1e-8 * np.max(np.abs(h0))


def test_generalized_jacobian_matches_free_floating_ee_twist(rigid):
    v0 = _zero_momentum_state(rigid, [0.2, -0.1, 0.3])
    traj = _simulate(rigid, v0, T=1.0, dt=0.0025)
    m, d = rigid.model, rigid.data
    for s in traj[::80]:
        G = rigid.generalized_jacobians(s.q)
        predicted = G["J_mEE"] @ s.v[rigid.idx.arm] + G["J_rEE"] @ s.v[rigid.idx.wheels]
        pin.forwardKinematics(m, d, s.q, s.v)
        pin.updateFramePlacements(m, d)
        tw = pin.getFrameVelocity(m, d, rigid.ee_frame_id, LWA)
        actual = np.concatenate([tw.angular, tw.linear])
        assert np.max(np.abs(predicted - actual)) < 1e-9 * max(1.0, np.max(np.abs(actual)))
        # and the base: J_m0 q̇m + J_r0 q̇r = seed base velocity
        base_seed = G["J_m0"] @ s.v[rigid.idx.arm] + G["J_r0"] @ s.v[rigid.idx.wheels]
        assert np.allclose(base_seed, base_velocity_to_seed(s.q, s.v[:6]), atol=1e-9)


def test_seed_adapter_round_trip_and_meaning(rigid):
    m, d = rigid.model, rigid.data
    for seed in range(5):
        q, v, _, _, _ = random_state(rigid, seed)
        s = base_velocity_to_seed(q, v[:6])
        assert np.allclose(base_velocity_from_seed(q, s), v[:6], atol=1e-14)
        assert np.allclose(seed_map(q) @ s, v[:6], atol=1e-14)
        pin.forwardKinematics(m, d, q, v)
        world = pin.getVelocity(m, d, 1, LWA)  # base-link origin, world axes
        assert np.allclose(s[3:6], world.linear, atol=1e-12)  # ṙ0 inertial
        assert np.allclose(s[0:3], v[3:6], atol=1e-14)  # ω0 in the base frame


def test_seed_blocks_are_locked_inertias(rigid):
    q, _, _, _, _ = random_state(rigid, 7)
    B = rigid.blocks(q)
    mtot = rigid.total_mass
    assert np.allclose(B["H_L"], mtot * np.eye(3), atol=1e-10)
    # H_omega = locked inertia about the base origin in the base frame (parallel-axis from ccrba)
    pin.ccrba(rigid.model, rigid.data, q, np.zeros(rigid.nv))
    Ig = rigid.data.Ig.inertia
    R = rigid.frame_pose(q, rigid.base_frame_id).rotation
    r = rigid.com(q) - q[:3]
    I_o_world = Ig + mtot * (r @ r * np.eye(3) - np.outer(r, r))
    assert np.allclose(B["H_omega"], R.T @ I_o_world @ R, atol=1e-9)
    assert np.allclose(B["H_eta"].shape, (0, 0))


def test_zero_mass_fixed_link_changes_nothing(tmp_path, rigid):
    urdf = (DATA / "arm3.urdf").read_text().replace(
        "</robot>", '<joint name="tag_joint" type="fixed"><parent link="l2"/><child link="tag"/>'
                    '<origin xyz="0.2 0.1 0" rpy="0.3 0 0"/></joint><link name="tag"/>\n</robot>')
    text = (DATA / "arm3.yaml").read_text()
    start, end = text.index("appendages:"), text.index("payloads:")
    (tmp_path / "arm3.urdf").write_text(urdf)
    (tmp_path / "m.yaml").write_text(text[:start] + text[end:])
    other = compile_path(tmp_path / "m.yaml")
    assert other.nv == rigid.nv and other.total_mass == pytest.approx(rigid.total_mass, abs=0)
    for seed in range(3):
        q, v, _, _, tau = random_state(rigid, seed)
        assert np.allclose(other.rigid_mass_matrix(q), rigid.rigid_mass_matrix(q), atol=1e-13)
        a1, _ = other.forward_dynamics(q, v, np.zeros(0), np.zeros(0), tau)
        a2, _ = rigid.forward_dynamics(q, v, np.zeros(0), np.zeros(0), tau)
        assert np.allclose(a1, a2, atol=1e-12)
