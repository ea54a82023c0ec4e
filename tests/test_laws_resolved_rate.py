"""Generalized-Jacobian resolved rate (Chevallard 2019) against oracles: the damped least-squares
identity, and the exponential decay of the end-effector error at rate K on a free-floating arm
integrated with RKMK4 and the SystemModel's forward dynamics."""

from __future__ import annotations

import math

import numpy as np
import pytest
import yaml

from sms_cli.dynamics.integrator import State, rkmk4_step
from sms_cli.sim.interfaces import EndEffectorRef
from sms_cli.sim.laws.resolved_rate import ResolvedRate, damped_pinv_solve

from conftest import DATA, compile_path, sm_sensed



@pytest.fixture(scope="module")
def rigid_arm3(tmp_path_factory):
    """arm3 without its modal panel (the GJM is the rigid free-floating one)."""
    d = yaml.safe_load((DATA / "arm3.yaml").read_text())
    d.pop("appendages")
    d["robot"]["urdf"] = str(DATA / "arm3.urdf")
    p = tmp_path_factory.mktemp("rr") / "arm3_rigid.yaml"
    p.write_text(yaml.safe_dump(d))
    return compile_path(p)


def test_damped_least_squares_identity():
    rng = np.random.default_rng(4)
    J = rng.normal(size=(3, 5))
    x = rng.normal(size=3)
    # far from singular: plain pseudo-inverse
    sol, lam2 = damped_pinv_solve(J, x, damping=0.1, threshold=1e-3)
    assert lam2 == 0.0 and np.allclose(sol, np.linalg.pinv(J) @ x)
    # near singular: Jᵀ (J Jᵀ + λ² I)⁻¹ x with λ² = λmax² (1 − (σmin/ε)²)
    U, S, Vt = np.linalg.svd(J, full_matrices=False)
    S[-1] = 1e-4
    Js = U @ np.diag(S) @ Vt
    sol, lam2 = damped_pinv_solve(Js, x, damping=0.1, threshold=0.05)
    assert lam2 == pytest.approx(0.01 * (1 - (1e-4 / 0.05) ** 2))
    assert np.allclose(sol, Js.T @ np.linalg.solve(Js @ Js.T + lam2 * np.eye(3), x))
    assert np.linalg.norm(sol) < np.linalg.norm(x) / (2 * math.sqrt(lam2)) + 1e-12  # bounded: σ/(σ²+λ²) ≤ 1/(2λ)


def _track(sm, law, target_offset, T, dt=2e-3):
    st = State(sm.q0.copy(), sm.v0.copy(), sm.eta0.copy(), sm.etadot0.copy())
    x0 = sm.ee_pose(st.q).translation.copy()
    ref = EndEffectorRef(x0 + target_offset, np.zeros(3))
    t, out = 0.0, []

    def accel(q, v, eta, etadot):
        tau = np.zeros(sm.nv)
        tau[sm.idx.arm] = law.torque(sm_sensed(sm, t, State(q, v, eta, etadot)), ref)
        return sm.forward_dynamics(q, v, eta, etadot, tau)

    for _ in range(int(round(T / dt))):
        out.append((t, ref.position - sm.ee_pose(st.q).translation, st.q[3:7].copy()))
        st = rkmk4_step(sm.model, st, dt, accel)
        t += dt
    return out


def test_gjm_resolved_rate_error_decays_exponentially_at_rate_K(rigid_arm3):
    sm = rigid_arm3
    K = 0.8
    # stiff inner rate loop: the lag q̇ − q̇_d ≈ (M/K_D) K q̇_d shifts the rate by O(K M/K_D) ≈ 0.3 %
    law = ResolvedRate(sm, K, kd=1000.0, damping=0.0, threshold=0.0)
    out = _track(sm, law, np.array([0.08, -0.05, 0.06]), T=3.0, dt=1e-3)
    e0 = np.linalg.norm(out[0][1])
    for t, e, _ in out[500::500]:
        assert np.linalg.norm(e) / e0 == pytest.approx(math.exp(-K * t), rel=0.01)
    # a straight line: the error keeps its direction
    d0 = out[0][1] / e0
    assert all(np.dot(e, d0) / np.linalg.norm(e) > 0.999 for t, e, _ in out[100::100])
    # the base really rotated (free-floating coupling)
    q_last = out[-1][2]
    assert 2 * math.acos(min(1.0, abs(q_last[3] * sm.q0[6] + q_last[:3] @ sm.q0[3:6]))) > 1e-3


def test_fixed_base_jacobian_misses_the_free_floating_target_rate(rigid_arm3):
    """The fixed-base Jacobian ignores the base reaction: its decay is not the designed e^{−Kt}."""
    sm = rigid_arm3
    K = 0.8
    law = ResolvedRate(sm, K, kd=1000.0, damping=0.0, threshold=0.0, jacobian="fixed_base")
    out = _track(sm, law, np.array([0.08, -0.05, 0.06]), T=2.0, dt=1e-3)
    e0 = np.linalg.norm(out[0][1])
    t, e, _ = out[-1]
    assert abs(np.linalg.norm(e) / e0 / math.exp(-K * t) - 1) > 0.05


def test_joint_rates_respect_the_urdf_velocity_limits(rigid_arm3):
    sm = rigid_arm3
    law = ResolvedRate(sm, 5.0, kd=10.0)
    st = State(sm.q0.copy(), sm.v0.copy(), sm.eta0.copy(), sm.etadot0.copy())
    s = sm_sensed(sm, 0.0, st)
    x0 = sm.ee_pose(st.q).translation
    qd = law.joint_rates(s, EndEffectorRef(x0 + np.array([1.0, 1.0, 1.0])))
    lim = np.array([a.max_velocity for a in sm.arm])
    assert np.max(np.abs(qd) / lim) == pytest.approx(1.0)


def test_orientation_rows_when_the_reference_has_a_quaternion(rigid_arm3):
    """With a target orientation, the 6-row GJM drives the full pose (3 joints: reachable when the
    target is the current orientation and position)."""
    sm = rigid_arm3

    class PoseRef(EndEffectorRef):
        pass

    st = State(sm.q0.copy(), sm.v0.copy(), sm.eta0.copy(), sm.etadot0.copy())
    pose = sm.ee_pose(st.q)
    import pinocchio as pin

    quat = pin.Quaternion(pose.rotation)
    ref = PoseRef(pose.translation.copy())
    ref.quat = np.array([quat.x, quat.y, quat.z, quat.w])
    ref.omega = np.zeros(3)
    law = ResolvedRate(sm, 1.0, kd=10.0)
    assert np.allclose(law.joint_rates(sm_sensed(sm, 0.0, st), ref), 0.0, atol=1e-12)


def test_factory_builds_resolved_rate_from_its_spec(rigid_arm3):
    from sms_cli.sim.laws import ResolvedRateSpec, build_resolved_rate

    spec = ResolvedRateSpec.model_validate({"gain": "1.5 1/s", "kd": [10, 10, 5], "damping": 0.02})
    law = build_resolved_rate(spec, rigid_arm3)
    assert np.allclose(law.K, 1.5) and np.allclose(law.kd, [10, 10, 5])
