"""Thrust allocation out of reach (sms_cli.thrusters.allocation): the persistent HiGHS instances (reach LP and
minimum-thrust LP) against fresh ``linprog`` calls (``warm=False``) on the shipped thruster layouts.

Oracles: the LP duals solved by HiGHS's interior-point method (another algorithm on another formulation) for
the reach s and for the minimum total thrust at s·w; B x = s w; the reach of a wrench built as B x with
0 ≤ x < x_max is 1."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import DATA, MISSIONS
from scipy.optimize import linprog

from sms_cli.thrusters import allocation
from sms_cli.thrusters.allocation import SHRINKS, Allocator


def _layouts() -> dict:
    """(B, x_max) of each shipped thruster set: S3c's servicer, S6's client, the tests' cube on Basilisk's hub."""
    from sms_cli.formation.client import compile_client
    from sms_cli.mission.load import load_mission
    from sms_cli.model import compile_system

    sets = {"s3c servicer": compile_system(load_mission(MISSIONS / "vicariotto_s3c_free_flying.yaml")).thrusters,
            "s6 client": compile_client(load_mission(MISSIONS / "vicariotto_s6_thrusters.yaml")).thrusters,
            "thrusters_cube": compile_system(load_mission(DATA / "thrusters_cube.yaml")).thrusters}
    out = {k: (ts.B, ts.max_force) for k, ts in sets.items()}
    # The cubes' capability sets are symmetric about 0 (reach(w) = reach(-w)); 14 random thrusters are not.
    rng = np.random.default_rng(11)
    pos, dirs = rng.uniform(-1, 1, (14, 3)), rng.normal(size=(14, 3))
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    out["random 14"] = (np.vstack([dirs.T, np.cross(pos, dirs).T]), rng.uniform(5, 25, 14))
    return out


SEEDS = {"s3c servicer": 1, "s6 client": 2, "thrusters_cube": 3, "random 14": 4}


@pytest.fixture(scope="module")
def layouts() -> dict:
    return _layouts()


def _reach_dual(B, fmax, w) -> float:
    """min fmaxᵀz + t  s.t. Bᵀy + z ≥ 0, −wᵀy + t ≥ 1, z, t ≥ 0 (the LP dual of max s, B x − s w = 0,
    0 ≤ x ≤ fmax, 0 ≤ s ≤ 1), by the interior-point method."""
    m, n = B.shape
    c = np.concatenate([np.zeros(m), fmax, [1.0]])
    A = np.zeros((n + 1, m + n + 1))
    A[:n, :m], A[:n, m:m + n] = -B.T, -np.eye(n)
    A[n, :m], A[n, -1] = w, -1.0
    b = np.concatenate([np.zeros(n), [-1.0]])
    res = linprog(c, A_ub=A, b_ub=b, bounds=[(None, None)] * m + [(0, None)] * (n + 1), method="highs-ipm")
    assert res.status == 0
    return res.fun


def _thrust_dual(B, fmax, w) -> float:
    """max wᵀy − fmaxᵀz  s.t. Bᵀy − z ≤ 1, z ≥ 0 (the LP dual of min 1ᵀx, B x = w, 0 ≤ x ≤ fmax)."""
    m, n = B.shape
    res = linprog(np.concatenate([-w, fmax]), A_ub=np.hstack([B.T, -np.eye(n)]), b_ub=np.ones(n),
                  bounds=[(None, None)] * m + [(0, None)] * n, method="highs-ipm")
    assert res.status == 0
    return -res.fun


def _commands(rng, B, fmax, count: int) -> list:
    """Wrenches [f; n] (N, N m) for the set (B, fmax): out of reach (a random direction, 1 to 20 times the bound
    Σ |b_i| fmax_i on any reachable |w|) interleaved with B x, 0 ≤ x ≤ fmax / 2, inside by construction, so each
    persistent instance restarts from bases of both kinds."""
    big = float(np.linalg.norm(B, axis=0) @ fmax)
    out = []
    for _ in range(count):
        u = rng.normal(size=6)
        out.append(u / np.linalg.norm(u) * big * rng.uniform(1, 20))
        out.append(B @ (rng.uniform(0, 0.5, fmax.size) * fmax))
    return out


@pytest.mark.parametrize("name", ["s3c servicer", "s6 client", "thrusters_cube", "random 14"])
def test_saturated_warm_equals_linprog_and_the_duals(layouts, name):
    """Out of reach: the persistent instances and fresh linprog give the same scale s (1e-9 relative), which is
    the reach LP's dual optimum pulled back by the first shrink δ = 1e-9 (to 5e-10, which resolves δ: the primal
    and dual optima differ by up to 1.1e-10 on the random layout, 5e-12 on the cubes, over 40 seeds); thrusts
    within bounds delivering s w (1e-9 |w|), the same total, which is the minimum-thrust dual at s w."""
    B, fmax = layouts[name]
    warm, cold = Allocator(B, fmax), Allocator(B, fmax, warm=False)
    assert warm._highs is not None and warm._reach_highs is not None and cold._reach_highs is None
    rng = np.random.default_rng(SEEDS[name])
    for k, w in enumerate(_commands(rng, B, fmax, 25)):
        a, b = warm.solve(w), cold.solve(w)
        assert a.saturated == b.saturated == (k % 2 == 0)  # the large commands out of reach, the small ones inside
        assert a.scale == pytest.approx(b.scale, rel=1e-9)
        for al in (a, b):
            assert np.all(al.thrust >= 0) and np.all(al.thrust <= fmax)
            assert np.abs(B @ al.thrust - al.scale * w).max() <= 1e-9 * np.linalg.norm(w)
        assert a.thrust.sum() == pytest.approx(b.thrust.sum(), rel=1e-9, abs=1e-9)
        if a.saturated:
            s = _reach_dual(B, fmax, w)
            assert s < 1 and a.scale == pytest.approx(s * (1 - SHRINKS[0]), rel=5e-10)
            assert warm.reach(w) == pytest.approx(s, rel=5e-10)
            assert a.thrust.sum() == pytest.approx(_thrust_dual(B, fmax, a.scale * w), rel=1e-8)
        else:
            assert a.scale == 1.0
    if name == "random 14":  # the set is not symmetric: a mirrored reach LP would give reach(-w)
        w = np.concatenate([rng.uniform(-1, 1, 3) * 90, rng.uniform(-1, 1, 3) * 110])
        assert abs(warm.reach(w) - warm.reach(-w)) > 1e-3 * warm.reach(w)


@pytest.mark.parametrize("name", ["s6 client", "random 14"])
def test_saturated_path_calls_no_linprog(layouts, name, monkeypatch):
    """With the persistent instances, a saturated command (minimum-thrust LP infeasible, reach LP, minimum-thrust LP
    at s (1 - δ) w) is solved without one fresh linprog; a slowly turning command as in a mission."""
    B, fmax = layouts[name]
    warm = Allocator(B, fmax)
    calls = []
    monkeypatch.setattr(allocation, "linprog", lambda *a, **k: calls.append(1) or linprog(*a, **k))
    u, v = np.linalg.qr(np.random.default_rng(2).normal(size=(6, 2)))[0].T  # orthonormal
    big = 2.0 * float(np.linalg.norm(B, axis=0) @ fmax)  # twice any reachable |w|
    for k in range(40):
        w = big * (np.cos(0.05 * k) * u + np.sin(0.05 * k) * v)
        assert warm.solve(w).saturated
    assert calls == []


@pytest.mark.parametrize("name", ["s3c servicer", "thrusters_cube"])
def test_reach_inside_the_set_is_one(layouts, name):
    """A wrench B x with 0 ≤ x ≤ 0.9 x_max (inside the set by construction) has reach exactly 1 (s's bound),
    warm and linprog, including right after an out-of-reach one."""
    B, fmax = layouts[name]
    warm, cold = Allocator(B, fmax), Allocator(B, fmax, warm=False)
    rng = np.random.default_rng(4)
    for _ in range(10):
        w = B @ (rng.uniform(0, 0.9, fmax.size) * fmax)
        assert warm.reach(10 * np.abs(w).max() * np.sign(w)) < 1  # a basis from a saturated reach first
        assert warm.reach(w) == 1.0 and cold.reach(w) == 1.0


def test_pure_torque_capability_is_the_hand_computation(layouts):
    """S6's client cube (side 1.2 m, 22 N): 4 F side about each axis, by the warm reach and by linprog."""
    B, fmax = layouts["s6 client"]
    for al in (Allocator(B, fmax), Allocator(B, fmax, warm=False)):
        for k in range(3, 6):
            assert al.pure_capability(np.eye(6)[k]) == pytest.approx(4 * 22.0 * 1.2, rel=1e-9)


def test_without_the_bundled_highs_module_linprog_solves(layouts, monkeypatch):
    """With scipy's private HiGHS module missing the allocator has no persistent instance and gives the
    same answers through linprog."""
    import sys

    B, fmax = layouts["thrusters_cube"]
    monkeypatch.setitem(sys.modules, "scipy.optimize._highspy", None)  # its import raises ImportError
    bare = Allocator(B, fmax)
    assert bare._highs is None and bare._reach_highs is None
    monkeypatch.undo()
    warm = Allocator(B, fmax)
    w = np.array([300.0, -200.0, 100.0, 150.0, 400.0, -90.0])
    a, b = bare.solve(w), warm.solve(w)
    assert a.saturated and a.scale == pytest.approx(b.scale, rel=1e-9)
    assert a.thrust.sum() == pytest.approx(b.thrust.sum(), rel=1e-9)
    assert allocation.linprog is linprog  # the fallback is scipy's linprog itself
