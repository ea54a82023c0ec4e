"""The compiled two-body decomposition (sms_cli/sim/compiled/pair_decomposition.py, wrapped by
sms_cli/formation/decomposition.py) against an independent numpy implementation of the formulas of
decomposition.py's module docstring, written out here (the code the kernels replaced, kept only as this oracle):
Pinocchio's ``Motion.action``, ``skew`` and ``SE3.toActionMatrixInverse``, numpy's LU solves and inverses.
Matrices to 1e-12 relative; the four shipped two-spacecraft missions (short) give the same trace and metrics to 1e-9
of their scale with the oracle (and test_pair_law_kernel's oracle law) patched in as with the kernels."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest

from sms_cli.formation import decomposition as dmod
from sms_cli.sim.compiled import pair_decomposition as k
from test_compiled_pair import _numbers, assert_traces_close

SEEDS = range(10)
I6 = np.eye(6)


# ---------------------------------------------------------------------- the oracle (numpy + Pinocchio)
def _ad(xi):
    return pin.Motion(np.asarray(xi, dtype=float)).action


def _sym(A):
    return 0.5 * (A + A.T)


def _rigid_coriolis(M, xi):
    a = _ad(xi)
    h = M @ xi
    Hbar = np.zeros((6, 6))
    Hbar[:3, 3:] = Hbar[3:, :3] = pin.skew(h[:3])
    Hbar[3:, 3:] = pin.skew(h[3:])
    return 0.5 * (M @ a - a.T @ M) - 0.5 * Hbar


def _decompose(M1, M2, g12):
    """(Ad⁻¹, M_tot, A*, S, S⁻¹, M_E) by numpy."""
    Ai = g12.toActionMatrixInverse()
    M_tot = _sym(M1 + Ai.T @ M2 @ Ai)
    A = np.linalg.solve(M_tot, Ai.T @ M2)
    S = np.block([[I6 - A @ Ai, A], [-Ai, I6]])
    S_inv = np.block([[I6, -A], [Ai, I6 - Ai @ A]])
    M_E = _sym(np.linalg.inv(np.linalg.inv(M2) + Ai @ np.linalg.solve(M1, Ai.T)))
    return Ai, M_tot, A, S, S_inv, M_E


def _s_inv_rate(M2, Ai, M_tot, A, V12, M1d, M2d):
    a = _ad(V12)
    Ai_dot = -a @ Ai
    Mtot_dot = M1d + Ai.T @ (M2d - a.T @ M2 - M2 @ a) @ Ai
    A_dot = np.linalg.solve(M_tot, Ai.T @ (M2d - a.T @ M2) - Mtot_dot @ A)
    return np.block([[np.zeros((6, 6)), -A_dot], [Ai_dot, -Ai_dot @ A - Ai @ A_dot]])


def _coriolis(M1, M2, xi1, xi2, V12, g12):
    Ai, M_tot, A, _, S_inv, _ = _decompose(M1, M2, g12)
    C12 = np.block([[_rigid_coriolis(M1, xi1), np.zeros((6, 6))], [np.zeros((6, 6)), _rigid_coriolis(M2, xi2)]])
    M12 = np.block([[M1, np.zeros((6, 6))], [np.zeros((6, 6)), M2]])
    return S_inv.T @ (C12 @ S_inv + M12 @ _s_inv_rate(M2, Ai, M_tot, A, V12, np.zeros((6, 6)), np.zeros((6, 6))))


class _OldDecomposition(dmod.PairDecomposition):
    """PairDecomposition whose S⁻¹ rate is the oracle's."""

    def S_inv_rate(self, V12, M1_dot=None, M2_dot=None):
        z = np.zeros((6, 6))
        return _s_inv_rate(self.M2, self.Ad12_inv, self.M_tot, self.A_star, V12, z if M1_dot is None else M1_dot,
                           z if M2_dot is None else M2_dot)


def _old_decompose(M1, M2, g12):
    M1, M2 = np.array(M1, float), np.array(M2, float)
    Ai, M_tot, A, S, S_inv, M_E = _decompose(M1, M2, g12)
    return _OldDecomposition(M1=M1, M2=M2, g12=g12.copy(), Ad12_inv=Ai, M_tot=M_tot, A_star=A, S=S, S_inv=S_inv, M_E=M_E)


def _old_coriolis(dec, xi1, xi2, V12=None):
    if V12 is None:
        V12 = xi2 - dec.Ad12_inv @ xi1
    return _coriolis(dec.M1, dec.M2, xi1, xi2, V12, dec.g12)


def _old_locked_state(self, M, v, i):
    """TwoBodyPlant.locked_state by numpy: ξ = M_bb⁻¹ (M v)_b, Λ = M_bb⁻¹ M_bθ, M_θθ − M_bθᵀ Λ."""
    b = self.body(i)
    Mbj = M[b.base_v, b.joints_v]
    Lam = np.linalg.solve(M[b.base_v, b.base_v], Mbj)
    return np.linalg.solve(M[b.base_v, b.base_v], M[b.base_v] @ v), Lam, M[b.joints_v, b.joints_v] - Mbj.T @ Lam


# ---------------------------------------------------------------------- cases
def _rel(a, b) -> float:
    return float(np.linalg.norm(np.asarray(a) - np.asarray(b)) / max(np.linalg.norm(b), 1e-300))


def _spacecraft_inertia(rng):
    """A spacecraft-like locked inertia: 50-2000 kg, CoM within 1 m of the base origin, principal moments 10-3000
    kg m² about random axes (conditioning of a real pair, up to ~1e4)."""
    m = rng.uniform(50.0, 2000.0)
    c = rng.uniform(-1.0, 1.0, 3)
    R = pin.exp3(rng.normal(size=3))
    d = rng.uniform(10.0, 3000.0, 3)
    return pin.Inertia(m, c, R @ np.diag(d) @ R.T).matrix()


def _case(seed: int):
    """(M1, M2, g12, ξ1, ξ2, V12): Pinocchio's random inertias on even seeds, spacecraft-like ones on odd seeds."""
    pin.seed(seed)
    rng = np.random.default_rng(seed)
    if seed % 2:
        M1, M2 = _spacecraft_inertia(rng), _spacecraft_inertia(rng)
        g12 = pin.SE3(pin.exp3(rng.normal(size=3)), rng.uniform(-20.0, 20.0, 3))
    else:
        M1, M2 = pin.Inertia.Random().matrix(), pin.Inertia.Random().matrix()
        g12 = pin.SE3.Random()
    return M1, M2, g12, rng.normal(size=6), rng.normal(size=6), rng.normal(size=6)


# ---------------------------------------------------------------------- kernels vs the oracle
@pytest.mark.parametrize("seed", SEEDS)
def test_ad_and_ad_inverse_are_pinocchios(seed):
    """ad_ξ is Pinocchio's Motion.action, Ad⁻¹ its SE3.toActionMatrixInverse (exact arithmetic: to round-off)."""
    _, _, g12, xi, _, _ = _case(seed)
    assert np.allclose(dmod.ad(xi), _ad(xi), rtol=0, atol=1e-15)
    out = np.empty((6, 6))
    k.ad_inverse(np.ascontiguousarray(g12.rotation), np.ascontiguousarray(g12.translation), out)
    assert _rel(out, g12.toActionMatrixInverse()) < 1e-14


@pytest.mark.parametrize("seed", SEEDS)
def test_decompose_matches_the_numpy_formulas(seed):
    """Ad⁻¹, M_tot (= M_L), A*, S, S⁻¹, M_E of ``decompose`` to 1e-12 of the oracle's (LU vs the kernels' Cholesky).
    M_E = (M2⁻¹ + Ad⁻¹ M1⁻¹ Ad⁻ᵀ)⁻¹ inverts twice, so both implementations' round-off grows with the inertias'
    conditioning: above cond 1e4 (Pinocchio's random inertias reach 3e5; the spacecraft-like ones stay below) its
    tolerance grows in proportion."""
    M1, M2, g12, _, _, _ = _case(seed)
    d = dmod.decompose(M1, M2, g12)
    Ai, M_tot, A, S, S_inv, M_E = _decompose(M1, M2, g12)
    for got, want in ((d.Ad12_inv, Ai), (d.M_tot, M_tot), (d.M_L, M_tot), (d.A_star, A), (d.S, S), (d.S_inv, S_inv)):
        assert _rel(got, want) < 1e-12
    cond = max(np.linalg.cond(M1), np.linalg.cond(M2))
    assert _rel(d.M_E, M_E) < 1e-12 * max(1.0, cond / 1e4)
    assert np.array_equal(d.M_tot, d.M_tot.T) and np.array_equal(d.M_E, d.M_E.T)


@pytest.mark.parametrize("seed", SEEDS)
def test_decompose_accepts_strided_inertias(seed):
    """Blocks of a mass matrix (non-contiguous views, as ``TwoBodyPlant.pair_decomposition`` passes) give the same."""
    M1, M2, g12, _, _, _ = _case(seed)
    big = np.zeros((14, 14))
    big[1:7, 1:7], big[8:14, 8:14] = M1, M2
    a, b = dmod.decompose(big[1:7, 1:7], big[8:14, 8:14], g12), dmod.decompose(M1, M2, g12)
    assert np.array_equal(a.S, b.S) and np.array_equal(a.M_E, b.M_E)


@pytest.mark.parametrize("seed", SEEDS)
def test_rigid_coriolis_matches_the_numpy_formula(seed):
    M1, _, _, xi, _, _ = _case(seed)
    assert _rel(dmod.rigid_coriolis(M1, xi), _rigid_coriolis(M1, xi)) < 1e-12


@pytest.mark.parametrize("seed", SEEDS)
def test_S_inv_rate_matches_the_numpy_formula(seed):
    """With and without inertia rates (random symmetric Ṁ1, Ṁ2)."""
    M1, M2, g12, _, _, V12 = _case(seed)
    rng = np.random.default_rng(100 + seed)
    M1d, M2d = _sym(rng.normal(size=(6, 6))), _sym(rng.normal(size=(6, 6)))
    d = dmod.decompose(M1, M2, g12)
    Ai, M_tot, A, _, _, _ = _decompose(M1, M2, g12)
    z = np.zeros((6, 6))
    assert _rel(d.S_inv_rate(V12), _s_inv_rate(M2, Ai, M_tot, A, V12, z, z)) < 1e-12
    assert _rel(d.S_inv_rate(V12, M1d, M2d), _s_inv_rate(M2, Ai, M_tot, A, V12, M1d, M2d)) < 1e-12
    S = _decompose(M1, M2, g12)[3]
    assert _rel(d.S_rate(V12, M1d, M2d), -S @ _s_inv_rate(M2, Ai, M_tot, A, V12, M1d, M2d) @ S) < 1e-12


@pytest.mark.parametrize("seed", SEEDS)
def test_coriolis_matches_the_numpy_formula(seed):
    """C* with the given V12 and with the default V12 = ξ2 − Ad⁻¹ ξ1."""
    M1, M2, g12, xi1, xi2, V12 = _case(seed)
    d = dmod.decompose(M1, M2, g12)
    assert _rel(dmod.coriolis(d, xi1, xi2, V12), _coriolis(M1, M2, xi1, xi2, V12, g12)) < 1e-12
    V_default = xi2 - g12.toActionMatrixInverse() @ xi1
    assert _rel(dmod.coriolis(d, xi1, xi2), _coriolis(M1, M2, xi1, xi2, V_default, g12)) < 1e-12


@pytest.mark.parametrize("seed", SEEDS)
def test_locked_state_matches_the_numpy_formulas(seed):
    """ξ_i, Λ_i and the joints' shape inertia of both bodies of a block-diagonal SPD mass matrix (bodies of 6 + 3 and
    6 + 0 velocities, the second without joints) to 1e-12; connection and locked_twist read the same kernel."""
    from types import SimpleNamespace

    from sms_cli.formation.plant import TwoBodyPlant

    rng = np.random.default_rng(seed)
    M = np.zeros((15, 15))
    for lo, n in ((0, 9), (9, 6)):
        B = rng.normal(size=(n, n))
        M[lo:lo + n, lo:lo + n] = B @ B.T + 0.1 * np.eye(n)
    v = rng.normal(size=15)
    bodies = [SimpleNamespace(base_v=slice(0, 6), joints_v=slice(6, 9)), SimpleNamespace(base_v=slice(9, 15),
                                                                                          joints_v=slice(15, 15))]
    plant = SimpleNamespace(body=lambda i: bodies[i])
    for i in range(2):
        got, want = TwoBodyPlant.locked_state(plant, M, v, i), _old_locked_state(plant, M, v, i)
        assert got[1].shape == want[1].shape and got[2].shape == want[2].shape
        for g, w in zip(got, want):
            assert _rel(g, w) < 1e-12 or (w.size == 0 and g.size == 0)
        plant.locked_state = lambda M_, v_, j: TwoBodyPlant.locked_state(plant, M_, v_, j)
        lam, mth = TwoBodyPlant.connection(plant, M, i)
        assert np.array_equal(lam, got[1]) and np.array_equal(mth, got[2])


# ---------------------------------------------------------------------- the missions, kernels vs the oracle
def _run(name: str, extra: str, tmp_path):
    from pathlib import Path

    from sms_cli.formation.metrics import formation_metrics
    from sms_cli.formation.simulate import FormationSimulation
    from sms_cli.formation.stage import prepared
    from sms_cli.mission.load import load_mission_text

    base = Path(__file__).resolve().parents[1] / "missions" / f"{name}.yaml"
    loaded = load_mission_text(f"extends: {base}\nformation: {{{extra}}}\n", base_dir=base.parent,
                               name=f"{name}_{tmp_path.name}.yaml")
    servicer, client = prepared(loaded)
    sim = FormationSimulation(loaded.mission, servicer, client, None, progress=False)
    r = sim.run()
    assert r.status == "completed"
    metrics = formation_metrics(r.trace, sim.spec, sim.names, r.wall_s, r.steps, r.engine)
    if r.capture is not None:
        metrics["capture"] = r.capture
    return r.trace, metrics


@pytest.mark.parametrize("name, extra", [
    ("vicariotto_s6_relative_hil", "duration: 60 s"),  # the internal pair, both pushes (at 20 s and 40 s)
    ("vicariotto_s4_relative_free_flying", "duration: 40 s"),
    ("vicariotto_s6_thrusters", "duration: 40 s"),
    ("caldera_capture_tumbling", ""),
])
def test_shipped_missions_run_the_same_on_the_kernels_as_on_the_numpy_formulas(name, extra, tmp_path, monkeypatch):
    """Every trace quantity and every metric (timing aside) to 1e-9 of its scale, the oracle's decompose, locked
    state and relative law (test_pair_law_kernel.old_law_call, with this file's C*) patched in where the simulation
    calls them."""
    from test_pair_law_kernel import old_law_call

    from sms_cli.formation import laws, plant

    new = _run(name, extra, tmp_path)
    monkeypatch.setattr(plant, "decompose", _old_decompose)
    monkeypatch.setattr(plant.TwoBodyPlant, "locked_state", _old_locked_state)
    monkeypatch.setattr(laws.RelativeLaw, "__call__", old_law_call)
    old = _run(name, extra, tmp_path)
    (a, ma_all), (p, mp_all) = new, old
    assert_traces_close(a, p)
    for section, y_all in mp_all.items():
        if section == "timing":
            continue
        mp, ma = dict(_numbers(y_all)), dict(_numbers(ma_all[section]))
        assert ma.keys() == mp.keys()
        scale = max([abs(y) for y in mp.values() if not math.isnan(y)] + [1e-300])
        for key, y in mp.items():
            assert abs(ma[key] - y) <= 1e-9 * scale or (math.isnan(y) and math.isnan(ma[key])), (section + key, ma[key], y)
