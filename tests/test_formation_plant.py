"""Two free-flying spacecraft in one Pinocchio model (sms_cli/formation/plant.py).

Bodies: the Vicariotto servicer (bus + 3 reaction wheels, missions/vicariotto_s3a_free_floating.yaml) as the
master "client", and the Astrobee with its arm (missions/astrobee_arm.yaml) as the "servicer".

Oracles: each SystemModel's own forward dynamics (per block, to 1e-12), the frame Jacobian's transpose for frame
wrenches, the per-body momenta of SystemModel.momentum, conservation of world momentum under internal wrenches
only (a central spring between a frame of each body, wheel and arm torques), conservation of energy with an
undamped spring at O(dt⁴), Ṁ by finite differences of the CRBA, and the plain RKMK4 run against the decomposed
(locked/shape) integrator.

Measured (this machine): decomposed vs plain over 20 s with a spring-damper between the bases, spinning wheels,
a moving arm and momentum in both locked and shape systems: max base position/attitude difference 3.7e-9 (m or rad)
at dt = 0.05 s, 2.3e-10 at dt = 0.025 s (ratio 15.9). Asserted: < 1e-8 at dt = 0.05 s and ratio > 8.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from conftest import DATA, MISSIONS, compile_path

from sms_cli.errors import InputError
from sms_cli.formation.plant import DecomposedIntegrator, TwoBodyPlant


@pytest.fixture(scope="module")
def bodies():
    return compile_path(MISSIONS / "vicariotto_s3a_free_floating.yaml"), compile_path(MISSIONS / "astrobee_arm.yaml")


@pytest.fixture(scope="module")
def plant(bodies):
    return TwoBodyPlant.build(*bodies)


G1 = pin.SE3(pin.exp3(np.array([0.1, 0.2, 0.3])), np.array([0.0, 0.0, 0.0]))
G2 = pin.SE3(pin.exp3(np.array([-0.3, 0.1, 0.2])), np.array([3.0, 0.5, 0.2]))
V1 = np.array([0.01, 0.02, 0.0, 0.01, 0.02, -0.01])
V2 = np.array([-0.02, 0.0, 0.01, 0.0, 0.03, 0.02])
WHEELS = np.array([30.0, -20.0, 10.0])
ARM = np.array([0.1, -0.2, 0.05])


def _state(plant):
    return plant.initial_state(G1, V1, G2, V2, joints_v=(WHEELS, ARM))


def _rel(a, b) -> float:
    return float(np.linalg.norm(np.asarray(a) - np.asarray(b)) / max(np.linalg.norm(b), 1e-300))


def _spring(plant, fa, fb, k, c=0.0, L=3.0):
    """Central spring(-damper) between the origins of frames fa (body 1) and fb (body 2): equal and opposite forces
    along the line joining the two points (internal: no net force or moment). Returns (interface, potential)."""
    data = plant.model.createData()

    def points(q, v=None):
        pin.forwardKinematics(plant.model, data, q, *(() if v is None else (v,)))
        out = []
        for f in (fa, fb):
            oMf = pin.updateFramePlacement(plant.model, data, f)
            vel = None if v is None else oMf.rotation @ pin.getFrameVelocity(plant.model, data, f).linear
            out.append((oMf, vel))
        return out

    def interface(q, v):
        (A, va), (B, vb) = points(q, v)
        d = B.translation - A.translation
        n = np.linalg.norm(d)
        u = d / n
        f = (k * (n - L) + c * ((vb - va) @ u)) * u  # force on body 1 (world)
        return [(fa, np.r_[A.rotation.T @ f, 0, 0, 0]), (fb, np.r_[-(B.rotation.T @ f), 0, 0, 0])]

    def potential(q):
        (A, _), (B, _) = points(q)
        return 0.5 * k * (np.linalg.norm(B.translation - A.translation) - L) ** 2

    return interface, potential


# ---------------------------------------------------------------------- structure
def test_index_maps(plant, bodies):
    b1, b2 = plant.bodies
    assert plant.nq == bodies[0].nq + bodies[1].nq and plant.nv == bodies[0].nv + bodies[1].nv
    assert (b1.name, b2.name) == ("client", "servicer")
    for b, sm in zip(plant.bodies, bodies):
        assert set(b.frames) == {f.name for f in sm.model.frames[1:]}
        for own, cid in b.frames.items():
            assert plant.model.frames[cid].name == f"{b.name}/{own}"
        assert plant.model.frames[b.base_frame_id].name == f"{b.name}/{sm.model.frames[sm.base_frame_id].name}"
        assert plant.model.frames[b.ee_frame_id].name == f"{b.name}/{sm.model.frames[sm.ee_frame_id].name}"
        assert plant.model.names[b.base_joint_id] == f"{b.name}/{sm.model.names[1]}"
    q, v = _state(plant)
    assert np.array_equal(v[b1.wheels_v], WHEELS) and np.array_equal(v[b2.arm_v], ARM)
    assert np.array_equal(q[b2.joints_q], bodies[1].q0[7:])
    for i, g in ((0, G1), (1, G2)):
        assert plant.base_pose(q, i).isApprox(g, 1e-14)
        assert plant.frame_pose(q, plant.bodies[i].base_frame_id).isApprox(g, 1e-14)  # base frame = root joint frame
    assert np.array_equal(plant.base_twist(v, "servicer"), V2)
    assert np.linalg.norm(plant.model.gravity.vector) == 0.0


def test_refuses_flexible_spring_and_same_names(bodies):
    with pytest.raises(InputError, match="not supported in two-spacecraft missions yet") as e:
        TwoBodyPlant.build(bodies[0], compile_path(MISSIONS / "pulsar_simple.yaml"))
    assert e.value.problems[0].field == "appendages"
    with pytest.raises(InputError, match="not supported in two-spacecraft missions yet") as e:
        TwoBodyPlant.build(compile_path(DATA / "hub_hinge.yaml"), bodies[1])
    assert e.value.problems[0].field == "springs"
    with pytest.raises(InputError, match="different"):
        TwoBodyPlant.build(*bodies, names=("a", "a"))


# ---------------------------------------------------------------------- dynamics vs each SystemModel
def _random_state(plant, bodies, seed):
    rng = np.random.default_rng(seed)
    pin.seed(seed)
    qs, vs = [], []
    for sm in bodies:
        q = pin.integrate(sm.model, sm.q0, rng.normal(size=sm.nv))
        q[:7] = pin.SE3ToXYZQUAT(pin.SE3.Random())
        qs.append(q)
        vs.append(rng.normal(size=sm.nv))
    return qs, vs, np.concatenate(qs), np.concatenate(vs), rng


@pytest.mark.parametrize("seed", range(4))
def test_blocks_equal_each_system_model(plant, bodies, seed):
    qs, vs, q, v, rng = _random_state(plant, bodies, seed)
    taus = [rng.normal(size=sm.nv) for sm in bodies]
    Fs = [rng.normal(size=6) for _ in bodies]
    a = plant.accelerations(q, v, np.concatenate(taus), tuple(Fs))
    for b, sm, qi, vi, ti, Fi in zip(plant.bodies, bodies, qs, vs, taus, Fs):
        t = ti.copy()
        t[:6] = Fi
        ref, _ = sm.forward_dynamics(qi, vi, np.zeros(0), np.zeros(0), t)
        assert _rel(a[b.v], ref) < 1e-12
    # base entries of tau are ignored in favour of the base wrenches
    t = np.concatenate(taus)
    t[plant.bodies[0].base_v] += 100.0
    assert np.array_equal(plant.accelerations(q, v, t, tuple(Fs)), a)


@pytest.mark.parametrize("seed", range(4))
def test_frame_wrenches_equal_jacobian_transpose(plant, bodies, seed):
    qs, vs, q, v, rng = _random_state(plant, bodies, seed)
    own = ("RW2_rotor", "gripper_center")  # a wheel rotor of body 1, the end-effector of body 2 (off its joint)
    ws = [rng.normal(size=6) for _ in own]
    fw = [(b.frames[name], w) for b, name, w in zip(plant.bodies, own, ws)]
    a = plant.accelerations(q, v, np.zeros(plant.nv), frame_wrenches=fw)
    for b, sm, qi, vi, name, w in zip(plant.bodies, bodies, qs, vs, own, ws):
        fid = sm.model.getFrameId(name, pin.FrameType.BODY)
        J = pin.computeFrameJacobian(sm.model, sm.model.createData(), qi, fid, pin.ReferenceFrame.LOCAL)
        ref, _ = sm.forward_dynamics(qi, vi, np.zeros(0), np.zeros(0), J.T @ w)
        assert _rel(a[b.v], ref) < 1e-12


# ---------------------------------------------------------------------- invariants
def test_momentum_and_locked_twists_against_each_body(plant, bodies):
    q, v = _state(plant)
    p = np.zeros(3)
    k = np.zeros(3)
    for b, sm in zip(plant.bodies, bodies):
        pi, ki = sm.momentum(q[b.q], v[b.v], about="origin")
        p, k = p + pi, k + ki
    h = plant.momentum_world(q, v)
    assert _rel(h, np.r_[p, k]) < 1e-12
    assert plant.kinetic_energy(q, v) == pytest.approx(sum(sm.energy(q[b.q], v[b.v], np.zeros(0), np.zeros(0))
                                                           for b, sm in zip(plant.bodies, bodies)), rel=1e-12)
    dec, xi1, xi2 = plant.decomposition(q, v)
    V_L, V_E = dec.locked_shape(xi1, xi2)
    # the locked momentum is the world momentum brought to frame 1
    assert _rel(dec.M_L @ V_L, G1.toActionMatrix().T @ h) < 1e-12
    assert _rel(xi2, plant.locked_twist(q, v, 1)) < 1e-14
    assert _rel(plant.locked_inertia(q, 0), dec.M1) < 1e-14
    # with the joints still, the locked twist is the base twist
    v0 = v.copy()
    for b in plant.bodies:
        v0[b.joints_v] = 0
    assert _rel(plant.locked_twist(q, v0, 0), V1) < 1e-14
    # with spinning wheels it is not (μ = ω + Λ θ̇)
    assert _rel(xi1, V1) > 1e-3


def _run(plant, q, v, dt, T, tau, interface):
    for _ in range(round(T / dt)):
        q, v = plant.step(q, v, dt, tau, interface=interface)
    return q, v


def test_momentum_conserved_under_internal_wrenches(plant):
    """Central spring-damper between the client's bus and the servicer's gripper centre (off its joint), wheel and
    arm torques: every wrench is internal. Measured worst relative drift over 400 steps of 5 ms: 4.4e-11."""
    q, v = _state(plant)
    b1, b2 = plant.bodies
    interface, _ = _spring(plant, b1.frames["bus"], b2.frames["gripper_center"], k=20.0, c=1.0)
    tau = np.zeros(plant.nv)
    tau[b1.wheels_v] = [0.05, -0.08, 0.03]
    tau[b2.arm_v] = [0.005, -0.002, 0.0]  # the gripper finger's 4.5e-5 kg m² makes the arm stiff: small torques
    h0 = plant.momentum_world(q, v)
    qs, vs = q, v
    worst = 0.0
    for _ in range(400):
        qs, vs = plant.step(qs, vs, 0.005, tau, interface=interface)
        worst = max(worst, _rel(plant.momentum_world(qs, vs), h0))
    assert worst < 1e-9
    assert _rel(vs, v) > 1e-2  # the run did move: the wrenches are not zero


def test_energy_conserved_at_fourth_order(plant):
    q, v = _state(plant)
    b1, b2 = plant.bodies
    interface, potential = _spring(plant, b1.frames["bus"], b2.frames["gripper_center"], k=20.0)
    tau = np.zeros(plant.nv)
    E0 = plant.kinetic_energy(q, v) + potential(q)
    errs = []
    for dt in (0.02, 0.01):  # measured 5.9e-8 and 2.0e-9 over 6 s
        qe, ve = _run(plant, q, v, dt, 6.0, tau, interface)
        errs.append(abs(plant.kinetic_energy(qe, ve) + potential(qe) - E0) / E0)
    assert errs[0] < 1e-6
    assert errs[0] / errs[1] > 8


# ---------------------------------------------------------------------- decomposed integrator
def test_coriolis_matrix_gives_mass_matrix_rate(plant, bodies):
    """The decomposed integrator takes Ṁ = C + Cᵀ from Pinocchio's Coriolis matrix: check it by finite differences."""
    q, v = _state(plant)
    h = 1e-6
    Mdot = (plant.mass_matrix(pin.integrate(plant.model, q, h * v)) - plant.mass_matrix(pin.integrate(plant.model, q, -h * v))) / (2 * h)
    C = pin.computeCoriolisMatrix(plant.model, plant.model.createData(), q, v)
    assert _rel(C + C.T, Mdot) < 1e-7


def test_decomposed_roundtrip(plant):
    q, v = _state(plant)
    D = DecomposedIntegrator(plant)
    y = D.to_decomposed(q, v)
    assert _rel(D.to_plain(q, y), v) < 1e-14
    dec, xi1, xi2 = plant.decomposition(q, v)
    assert _rel(y[:12], np.concatenate(dec.locked_shape(xi1, xi2))) < 1e-14


def test_decomposed_and_plain_give_the_same_absolute_trajectories(plant):
    """Same mission twice: spring-damper between the bases, wheels spinning, arm moving, momentum in both locked
    and shape systems. Max base position (m) / attitude (rad) difference over 20 s: < 1e-8 at dt = 0.05 s, and
    it shrinks by > 8× (4th order: ~16×) at dt = 0.025 s."""
    q0, v0 = _state(plant)
    b1, b2 = plant.bodies
    interface, _ = _spring(plant, b1.base_frame_id, b2.base_frame_id, k=20.0, c=5.0)
    tau = np.zeros(plant.nv)
    D = DecomposedIntegrator(plant)
    dec, xi1, xi2 = plant.decomposition(q0, v0)
    V_L, V_E = dec.locked_shape(xi1, xi2)
    assert min(np.linalg.norm(V_L), np.linalg.norm(V_E)) > 1e-2
    errs = []
    for dt in (0.05, 0.025):
        qa, va = q0.copy(), v0.copy()
        qb, yb = q0.copy(), D.to_decomposed(q0, v0)
        err = 0.0
        for _ in range(round(20.0 / dt)):
            qa, va = plant.step(qa, va, dt, tau, interface=interface)
            qb, yb = D.step(qb, yb, dt, tau, interface=interface)
            for i in (0, 1):
                A, B = plant.base_pose(qa, i), plant.base_pose(qb, i)
                err = max(err, np.linalg.norm(A.translation - B.translation),
                          np.linalg.norm(pin.log3(A.rotation.T @ B.rotation)))
        errs.append(err)
    assert np.linalg.norm(plant.base_pose(qa, 1).translation - G2.translation) > 0.05  # it moved
    assert errs[0] < 1e-8
    assert errs[0] / errs[1] > 8


def test_world_momentum_error_is_fourth_order(plant):
    """Both bases tumbling (|ω| 1.7 and 1.6 rad/s), wheels spinning, no inputs: the world momentum drift is the
    RKMK4 truncation error. Measured relative drift over 4 s at dt 0.04 / 0.02 / 0.01: 1.2e-6, 7.6e-8, 4.7e-9
    (ratios 16.1, 16.1); with the dexp⁻¹ correction on the first free-flyer only: 8.8e-6, 2.1e-6, 5.2e-7
    (ratios 4.2, 4.0). Asserted: each ratio in [13, 19]."""
    Va = np.array([0.3, -0.2, 0.1, 0.5, 1.5, -0.8])
    Vb = np.array([-0.2, 0.4, 0.1, 1.2, -0.6, 0.9])
    q, v = plant.initial_state(G1, Va, G2, Vb, joints_v=(np.array([20.0, -30.0, 10.0]), np.zeros(3)))
    h0 = plant.momentum_world(q, v)
    errs = [_rel(plant.momentum_world(*_run(plant, q, v, dt, 4.0, np.zeros(plant.nv), None)), h0) for dt in (0.04, 0.02, 0.01)]
    assert 13 < errs[0] / errs[1] < 19 and 13 < errs[1] / errs[2] < 19
