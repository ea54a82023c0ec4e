"""Real thrusters (issue #12 item 1, sms_cli.thrusters): allocation, modulation, propellant, capability.

Oracles: an independent LP (the dual, by HiGHS's interior-point solver) for optimality; the hand
computation of the cube's per-axis capability (4F, 4F·s); Tsiolkovsky for a constant burn; the
modulation bound stated in sms_cli.thrusters.modulation."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import linprog

from sms_cli.thrusters.allocation import Allocator
from sms_cli.thrusters.capability import axis_capability, missing_directions
from sms_cli.thrusters.layout import G0, ThrusterSet, cube_thrusters
from sms_cli.thrusters.modulation import impulse_error_bound, on_times

F, ISP, SIDE = 22.0, 291.0, 1.5


def cube_set(mib=0.025, quant=9.9e-7, side=SIDE, centre=(0.0, 0.0, 0.0)) -> ThrusterSet:
    names, pos, dirs, f, isp = zip(*cube_thrusters(side, F, ISP, centre))
    return ThrusterSet(list(names), np.array(pos), np.array(dirs), np.array(f), np.array(isp), 0.2, mib, quant,
                       np.zeros(3), 10.0)


def test_cube_capability_is_the_hand_computation():
    """Pure force per axis: the 4 thrusters of one face, 4F; pure torque: 8 thrusters with lever s/2, 4F·s."""
    ts = cube_set(centre=(0.1, -0.2, 0.05))
    assert ts.n == 24
    for a in axis_capability(ts, "force").values():
        assert a == pytest.approx(4 * F, rel=1e-9)
    for a in axis_capability(ts, "torque").values():
        assert a == pytest.approx(4 * F * SIDE, rel=1e-9)
    assert np.linalg.matrix_rank(ts.B) == 6  # full 6-D authority
    assert missing_directions(ts, "force") == [] and missing_directions(ts, "torque") == []


def test_layout_without_x_torque_is_found():
    """Thrusters in the x-y plane at z = 0 pushing along x and y (couples about z): no torque about x or y."""
    pos = np.array([[0, 1, 0], [0, -1, 0], [0, 1, 0], [0, -1, 0], [1, 0, 0], [-1, 0, 0], [1, 0, 0], [-1, 0, 0]], float)
    dirs = np.array([[1, 0, 0], [-1, 0, 0], [-1, 0, 0], [1, 0, 0], [0, 1, 0], [0, -1, 0], [0, -1, 0], [0, 1, 0]], float)
    ts = ThrusterSet([f"t{i}" for i in range(8)], pos, dirs, np.full(8, F), np.full(8, ISP), 0.2, 0.0, 0.0,
                     np.zeros(3), 1.0)
    assert set(missing_directions(ts, "torque")) == {"+x torque", "-x torque", "+y torque", "-y torque"}


def _dual_optimum(B, fmax, w) -> float:
    """max wᵀy − fmaxᵀz  s.t. Bᵀy − z ≤ 1, z ≥ 0 (the LP dual of min 1ᵀx, Bx = w, 0 ≤ x ≤ fmax)."""
    m, n = B.shape
    c = np.concatenate([-w, fmax])
    A = np.hstack([B.T, -np.eye(n)])
    res = linprog(c, A_ub=A, b_ub=np.ones(n), bounds=[(None, None)] * m + [(0, None)] * n, method="highs-ipm")
    assert res.status == 0
    return -res.fun


def test_allocation_is_feasible_bounded_and_optimal():
    ts = cube_set()
    alloc = Allocator(ts.B, ts.max_force)
    rng = np.random.default_rng(12)
    for _ in range(40):
        w = np.concatenate([rng.uniform(-40, 40, 3), rng.uniform(-60, 60, 3)])
        a = alloc.solve(w)
        assert not a.saturated
        assert np.all(a.thrust >= 0) and np.all(a.thrust <= ts.max_force)
        assert np.allclose(ts.B @ a.thrust, w, atol=1e-7)
        assert a.thrust.sum() == pytest.approx(_dual_optimum(ts.B, ts.max_force, w), rel=1e-7, abs=1e-7)


def test_allocation_out_of_reach_is_scaled_along_the_command():
    ts = cube_set()
    alloc = Allocator(ts.B, ts.max_force)
    w = np.array([0, 0, 0, 1000.0, 0, 0])  # above 4 F s = 132 N m
    a = alloc.solve(w)
    assert a.saturated and np.all(a.thrust >= 0) and np.all(a.thrust <= ts.max_force + 1e-12)
    assert ts.B @ a.thrust == pytest.approx(a.scale * w, abs=1e-6)
    assert a.scale * 1000.0 == pytest.approx(4 * F * SIDE, rel=1e-6)


@pytest.mark.parametrize("mib,quant", [(0.025, 9.9e-7), (0.0, 1e-2), (0.025, 0.05)])
def test_modulation_bound_and_mib(mib, quant):
    """Cycle-averaged delivered wrench B (F∘t_on)/T within Σ|b_i| F_i e_i / T of the allocated B x; no
    on-time in (0, mib)."""
    ts = cube_set(mib=mib, quant=quant)
    alloc = Allocator(ts.B, ts.max_force)
    rng = np.random.default_rng(3)
    T = ts.firing_cycle
    for _ in range(30):
        w = np.concatenate([rng.uniform(-20, 20, 3), rng.uniform(-30, 30, 3)])
        x = alloc.solve(w).thrust
        t = on_times(x, ts.max_force, T, mib, quant)
        assert np.all((t == 0) | (t >= mib)) and np.all(t <= T)
        e = impulse_error_bound(x, ts.max_force, T, mib, quant)
        assert np.all(np.abs(t - x / ts.max_force * T) <= e + 1e-15)
        delivered = ts.B @ (ts.max_force * t) / T
        bound = np.abs(ts.B) @ (ts.max_force * e) / T
        assert np.all(np.abs(delivered - w) <= bound + 1e-9)


def test_plant_sees_each_firing_exactly():
    """Over a tick of k cycles cut into plant steps that do not line up with the switchings, the thrust
    impulses the drive applies are k F∘t_on and the mass flow is ṁ∘t_on."""
    from sms_cli.thrusters.drive import ThrusterDrive

    class _Model:
        def __init__(self):
            import pinocchio as pin

            self.model = pin.Model()
            self.model.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), "base")
            self.model.inertias[1] = pin.Inertia(500.0, np.zeros(3), np.eye(3) * 100)
            self.base_joint_id = 1

    ts = cube_set()
    d = ThrusterDrive(_Model(), ts)
    w = np.array([3.0, -1.0, 0.5, 10.0, -7.0, 2.0])
    d.command(0.0, w)
    total = np.zeros(ts.n)
    dt, t = 0.03, 0.0
    for _ in range(20):  # 0.6 s = 3 cycles
        d.step(None, t, dt, np.zeros(6), lambda s, tau, h, a: s)
        total += d.thrust_step * dt
        t += dt
    assert total == pytest.approx(3 * ts.max_force * d.on, abs=1e-9)
    # the cycle-averaged delivered wrench is the commanded one within the modulation bound
    e = impulse_error_bound(d.thrust_cmd, ts.max_force, ts.firing_cycle, ts.mib, ts.quantization)
    bound = np.abs(ts.B) @ (ts.max_force * e) / ts.firing_cycle
    assert np.all(np.abs(ts.B @ total / (3 * ts.firing_cycle) - w) <= bound + 1e-9)
    assert np.any(d.on > 0) and np.any((d.on == 0) & (d.thrust_cmd > 0))  # some fire, some are below the MIB
    assert d.used == pytest.approx(3 * float(ts.mass_flow @ d.on), rel=1e-12)


def test_constant_burn_is_tsiolkovsky(tmp_path):
    """One thruster through the system CoM (tank there too) fired for 120 s: Δv = Isp g0 ln(m0/m1) to 1e-9
    (relative) and the propellant used is ṁ t."""
    from conftest import ROOT

    from sms_cli.dynamics.integrator import State
    from sms_cli.mission.load import load_mission
    from sms_cli.model.compiler import compile_system
    from sms_cli.thrusters.drive import ThrusterDrive

    sm = compile_system(load_mission(ROOT / "tests" / "data" / "thrusters_cube.yaml"))
    com = np.asarray(sm.model.inertias[sm.base_joint_id].lever, float)  # the hub's wheels sit at its CoM
    ts = ThrusterSet(["main"], com[None, :], np.array([[1.0, 0, 0]]), np.array([F]), np.array([ISP]), 0.2, 0.0, 0.0,
                     com, 5.0)
    d = ThrusterDrive(sm, ts)
    d.on = np.array([ts.firing_cycle])  # always on
    m0 = sm.total_mass
    s = State(sm.q0.copy(), np.zeros(sm.nv), sm.eta0.copy(), sm.etadot0.copy())
    from sms_cli.dynamics.integrator import rkmk4_step

    def advance(s, tau, h, a):
        return rkmk4_step(sm.model, s, h, lambda q, v, e, ed: sm.forward_dynamics(q, v, e, ed, tau))

    t, dt = 0.0, 0.1
    for _ in range(1200):
        s = d.step(s, t, dt, np.zeros(sm.nv), advance)
        t += dt
    m1 = sm.total_mass
    assert d.used == pytest.approx(F / (ISP * G0) * 120.0, rel=1e-12)
    assert m0 - m1 == pytest.approx(d.used, rel=1e-9)
    dv = np.linalg.norm(sm.momenta(s.q, s.v)[0]) / m1
    assert dv == pytest.approx(ISP * G0 * np.log(m0 / m1), rel=1e-9)
    assert np.linalg.norm(s.v[3:6]) < 1e-12  # through the CoM: no rotation


def test_warm_highs_equals_linprog():
    """The persistent HiGHS instance and a fresh ``linprog(method="highs")`` give the same optimum."""
    ts = cube_set()
    warm, cold = Allocator(ts.B, ts.max_force), Allocator(ts.B, ts.max_force, warm=False)
    assert warm._highs is not None
    rng = np.random.default_rng(5)
    for _ in range(30):
        w = np.concatenate([rng.uniform(-60, 60, 3), rng.uniform(-90, 90, 3)])
        a, b = warm.solve(w), cold.solve(w)
        assert a.saturated == b.saturated
        assert a.thrust.sum() == pytest.approx(b.thrust.sum(), rel=1e-9, abs=1e-9)
        assert ts.B @ a.thrust == pytest.approx(a.scale * w, abs=1e-6)


def test_vertex_enumeration_optimum_on_a_small_layout():
    """Brute force: an LP optimum is at a vertex (6 basic thrusts, the others at 0 or max); enumerate all
    of them for an 8-thruster set and compare the best total with the allocation."""
    from itertools import combinations, product as prod

    rng = np.random.default_rng(7)
    pos = rng.uniform(-1, 1, (8, 3))
    dirs = rng.normal(size=(8, 3))
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    fmax = rng.uniform(5, 20, 8)
    B = np.vstack([dirs.T, np.cross(pos, dirs).T])
    alloc = Allocator(B, fmax)
    for _ in range(5):
        x_true = rng.uniform(0, 1, 8) * fmax
        w = B @ x_true  # reachable by construction
        best = np.inf
        for basis in combinations(range(8), 6):
            rest = [j for j in range(8) if j not in basis]
            Bb = B[:, basis]
            if abs(np.linalg.det(Bb)) < 1e-12:
                continue
            for at in prod(*[(0.0, fmax[j]) for j in rest]):
                xb = np.linalg.solve(Bb, w - B[:, rest] @ np.array(at))
                if np.all(xb >= -1e-9) and np.all(xb <= fmax[list(basis)] + 1e-9):
                    best = min(best, xb.sum() + sum(at))
        a = alloc.solve(w)
        assert not a.saturated
        assert a.thrust.sum() == pytest.approx(best, rel=1e-8)
