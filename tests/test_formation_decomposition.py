"""Two- and n-spacecraft locked/shape decomposition (sms_cli/formation/decomposition.py, Vicariotto 2023 §5.3–5.5)
against oracles the code cannot tune: the definition M* = S⁻ᵀ M12 S⁻¹ and the separate closed form of M_E
(erratum-corrected L950), the body twist of g12 by finite differences of pin.log6, kinetic energy and power
(wrench·twist) invariance, the 1-D two-mass closed forms, Pinocchio's nonLinearEffects for a free body, the
skew identity of Ṁ* − 2C* and the decomposed equations of motion with Ṁ*, Ṡ by finite differences along a
rigid two-body motion whose accelerations come from M ξ̇ − ad_ξᵀ M ξ = F.

Random inertias are ``pin.Inertia.Random()`` (SPD, mass, lever and rotational inertia all random) and poses
``pin.SE3.Random()``, seeded."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from sms_cli.formation.decomposition import (
    PairDecomposition, ad, closed_form_M_E, coriolis, coriolis_blocks, decompose, decompose_n, rigid_coriolis)

SEEDS = range(8)


def _rel(a, b) -> float:
    return float(np.linalg.norm(np.asarray(a) - np.asarray(b)) / max(np.linalg.norm(b), 1e-300))


def _case(seed: int):
    """Random (M1, M2, g1, g2, ξ1, ξ2)."""
    pin.seed(seed)
    rng = np.random.default_rng(seed)
    M1, M2 = pin.Inertia.Random().matrix(), pin.Inertia.Random().matrix()
    g1, g2 = pin.SE3.Random(), pin.SE3.Random()
    return M1, M2, g1, g2, rng.normal(size=6), rng.normal(size=6)


def _M12(M1, M2):
    out = np.zeros((12, 12))
    out[:6, :6], out[6:, 6:] = M1, M2
    return out


def _at(g1, g2, xi1, xi2, t):
    """g12 at time t along g_i exp(t ξ_i) (its first derivative at t = 0 is that of any motion with twists ξ_i)."""
    return (g1 * pin.exp6(t * xi1)).inverse() * (g2 * pin.exp6(t * xi2))


@pytest.mark.parametrize("seed", SEEDS)
def test_inertia_is_block_diagonal_and_matches_closed_forms(seed):
    M1, M2, g1, g2, *_ = _case(seed)
    g12 = g1.inverse() * g2
    d = decompose(M1, M2, g12)
    Mstar = d.S_inv.T @ _M12(M1, M2) @ d.S_inv
    scale = np.linalg.norm(Mstar)
    assert np.linalg.norm(Mstar[:6, 6:]) / scale < 1e-12
    assert np.linalg.norm(Mstar[6:, :6]) / scale < 1e-12
    assert _rel(Mstar[:6, :6], d.M_L) < 1e-12
    assert _rel(d.M_L, M1 + g12.toActionMatrixInverse().T @ M2 @ g12.toActionMatrixInverse()) < 1e-12
    # M_E is an inverse of a sum of inverses (condition numbers up to ~1e3 here): 1e-10
    assert _rel(Mstar[6:, 6:], d.M_E) < 1e-10
    assert _rel(d.M_E, closed_form_M_E(M1, M2, g12)) < 1e-10
    assert _rel(d.S @ d.S_inv, np.eye(12)) < 1e-12
    assert _rel(d.M_star, Mstar) < 1e-12


@pytest.mark.parametrize("seed", SEEDS)
def test_velocities_momentum_energy(seed):
    M1, M2, g1, g2, xi1, xi2 = _case(seed)
    g12 = g1.inverse() * g2
    d = decompose(M1, M2, g12)
    V_L, V_E = d.locked_shape(xi1, xi2)
    # V_E is the body twist of g12 = g1⁻¹ g2 (central difference of log6, O(h²))
    h = 1e-5
    fd = pin.log6(_at(g1, g2, xi1, xi2, -h).inverse() * _at(g1, g2, xi1, xi2, h)).vector / (2 * h)
    assert _rel(V_E, fd) < 1e-8
    # V_L = M_tot⁻¹ H with H the total momentum: world momentum of both bodies, brought to frame 1
    H_world = g1.dualAction @ M1 @ xi1 + g2.dualAction @ M2 @ xi2
    H1 = g1.toActionMatrix().T @ H_world
    assert _rel(d.momentum(xi1, xi2), H1) < 1e-12
    assert _rel(d.M_L @ V_L, H1) < 1e-12
    # energy
    T_L, T_E = d.energies(V_L, V_E)
    T = 0.5 * xi1 @ M1 @ xi1 + 0.5 * xi2 @ M2 @ xi2
    assert T_L + T_E == pytest.approx(T, rel=1e-12)
    # inverse
    b1, b2 = d.body_twists(V_L, V_E)
    assert _rel(b1, xi1) < 1e-12 and _rel(b2, xi2) < 1e-12


@pytest.mark.parametrize("seed", SEEDS)
def test_wrench_map_power_and_inverse(seed):
    M1, M2, g1, g2, xi1, xi2 = _case(seed)
    rng = np.random.default_rng(100 + seed)
    F1, F2 = rng.normal(size=6), rng.normal(size=6)
    d = decompose(M1, M2, g1.inverse() * g2)
    F_L, F_E = d.to_locked_shape(F1, F2)
    V_L, V_E = d.locked_shape(xi1, xi2)
    # power conjugacy: the same power in both descriptions
    assert F_L @ V_L + F_E @ V_E == pytest.approx(F1 @ xi1 + F2 @ xi2, rel=1e-11, abs=1e-12)
    # F_L is the total wrench in frame 1 (world wrenches summed, brought to frame 1)
    F_world = g1.dualAction @ F1 + g2.dualAction @ F2
    assert _rel(F_L, g1.toActionMatrix().T @ F_world) < 1e-12
    G1, G2 = d.to_bodies(F_L, F_E)
    assert _rel(G1, F1) < 1e-11 and _rel(G2, F2) < 1e-11
    L2, E2 = d.to_locked_shape(*d.to_bodies(F1, F2))
    assert _rel(L2, F1) < 1e-11 and _rel(E2, F2) < 1e-11


@pytest.mark.parametrize("seed", SEEDS)
def test_shape_effort(seed):
    M1, M2, g1, g2, *_ = _case(seed)
    F_E = np.random.default_rng(200 + seed).normal(size=6)
    d = decompose(M1, M2, g1.inverse() * g2)
    F1, F2 = d.shape_effort(F_E, "both")
    L, E = d.to_locked_shape(F1, F2)
    assert np.linalg.norm(L) < 1e-12 * np.linalg.norm(F_E) * 10
    assert _rel(E, F_E) < 1e-12
    assert _rel(F2, F_E) < 1e-15
    F1, F2 = d.shape_effort(F_E, "master")
    assert not F2.any()
    assert _rel(d.to_locked_shape(F1, F2)[1], F_E) < 1e-10
    F1, F2 = d.shape_effort(F_E, "other")
    assert not F1.any()
    assert _rel(d.to_locked_shape(F1, F2)[1], F_E) < 1e-10
    with pytest.raises(ValueError):
        d.shape_effort(F_E, "servicer")


def test_two_masses_on_a_line():
    """§5.2 toy: point masses m1, m2 along x (tiny rotational inertia): M_L = m1 + m2, M_E = m1 m2/(m1 + m2),
    F_L = f1 + f2, F_E = (m1 f2 − m2 f1)/(m1 + m2), V_L the CoM velocity, V_E = ẋ2 − ẋ1."""
    m1, m2, f1, f2, x1d, x2d = 3.0, 7.0, 2.0, -5.0, 0.4, -1.1
    Y = lambda m: pin.Inertia(m, np.zeros(3), 1e-6 * np.eye(3)).matrix()
    g1 = pin.SE3(np.eye(3), np.array([1.0, 0, 0]))
    g2 = pin.SE3(np.eye(3), np.array([4.5, 0, 0]))
    d = decompose(Y(m1), Y(m2), g1.inverse() * g2)
    assert d.M_L[0, 0] == pytest.approx(m1 + m2, rel=1e-14)
    assert d.M_E[0, 0] == pytest.approx(m1 * m2 / (m1 + m2), rel=1e-12)
    e = np.eye(6)[0]
    F_L, F_E = d.to_locked_shape(f1 * e, f2 * e)
    assert F_L == pytest.approx(e * (f1 + f2), abs=1e-12)
    assert F_E == pytest.approx(e * (m1 * f2 - m2 * f1) / (m1 + m2), abs=1e-12)
    V_L, V_E = d.locked_shape(x1d * e, x2d * e)
    assert V_L == pytest.approx(e * (m1 * x1d + m2 * x2d) / (m1 + m2), abs=1e-12)
    assert V_E == pytest.approx(e * (x2d - x1d), abs=1e-14)


@pytest.mark.parametrize("seed", SEEDS)
def test_rigid_coriolis_is_skew_and_matches_pinocchio(seed):
    M1, _, _, _, xi1, _ = _case(seed)
    C = rigid_coriolis(M1, xi1)
    assert np.abs(C + C.T).max() < 1e-13 * np.abs(C).max()
    assert _rel(C @ xi1, -ad(xi1).T @ M1 @ xi1) < 1e-12
    # Pinocchio: one free-flying body with this inertia, zero gravity: nle = C(ξ) ξ
    model = pin.Model()
    j = model.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), "ff")
    model.appendBodyToJoint(j, pin.Inertia.FromDynamicParameters(_dyn_params(M1)), pin.SE3.Identity())
    model.gravity = pin.Motion.Zero()
    data = model.createData()
    q = pin.SE3ToXYZQUAT(pin.SE3.Random())
    assert _rel(pin.crba(model, data, q), M1) < 1e-12
    assert _rel(pin.nonLinearEffects(model, data, q, xi1), C @ xi1) < 1e-12


def _dyn_params(M):
    """Dynamic parameters [m, mc, I_origin (xx, xy, yy, xz, yz, zz)] of a 6×6 spatial inertia (linear first)."""
    m = M[0, 0]
    mc = np.array([M[5, 1], M[3, 2], M[4, 0]])  # M[:3, 3:] = −m[c]×
    Io = M[3:, 3:]
    return np.array([m, *mc, Io[0, 0], Io[0, 1], Io[1, 1], Io[0, 2], Io[1, 2], Io[2, 2]])


def _rigid_accel(M, xi, F):
    """ξ̇ of a rigid body: M ξ̇ − ad_ξᵀ M ξ = F (3.6)."""
    return np.linalg.solve(M, F + ad(xi).T @ M @ xi)


@pytest.mark.parametrize("seed", SEEDS)
def test_decomposed_coriolis_skew_and_equations_of_motion(seed):
    M1, M2, g1, g2, xi1, xi2 = _case(seed)
    rng = np.random.default_rng(300 + seed)
    F1, F2 = rng.normal(size=6), rng.normal(size=6)
    d = decompose(M1, M2, g1.inverse() * g2)
    Cs = coriolis(d, xi1, xi2)
    h = 1e-5
    dm, dp = (decompose(M1, M2, _at(g1, g2, xi1, xi2, s)) for s in (-h, h))
    Mstar_dot = (dp.M_star - dm.M_star) / (2 * h)
    K = Mstar_dot - 2 * Cs
    assert np.abs(K + K.T).max() < 1e-7 * np.abs(Cs).max()
    # M* V̇ + C* V = [F_L; F_E] with V̇ = S ξ̇ + Ṡ ξ, Ṡ by finite differences, ξ̇ from the rigid-body equations
    xi = np.concatenate([xi1, xi2])
    xid = np.concatenate([_rigid_accel(M1, xi1, F1), _rigid_accel(M2, xi2, F2)])
    S_dot_fd = (dp.S - dm.S) / (2 * h)
    assert _rel(d.S_rate(xi2 - d.Ad12_inv @ xi1), S_dot_fd) < 1e-8
    Vdot = d.S @ xid + S_dot_fd @ xi
    lhs = d.M_star @ Vdot + Cs @ (d.S @ xi)
    assert _rel(lhs, np.concatenate(d.to_locked_shape(F1, F2))) < 1e-8
    blocks = coriolis_blocks(Cs)
    assert np.array_equal(blocks["C_LE"], Cs[:6, 6:]) and np.array_equal(blocks["C_EL"], Cs[6:, :6])
    assert np.array_equal(blocks["C_LL"], Cs[:6, :6]) and np.array_equal(blocks["C_EE"], Cs[6:, 6:])


@pytest.mark.parametrize("seed", SEEDS[:4])
def test_S_inv_rate_with_changing_locked_inertias(seed):
    """d/dt S⁻¹ with Ṁ1, Ṁ2 ≠ 0 (a moving arm changes a spacecraft's locked inertia) against finite differences."""
    M1, M2, g1, g2, xi1, xi2 = _case(seed)
    pin.seed(50 + seed)
    M1d, M2d = pin.Inertia.Random().matrix(), pin.Inertia.Random().matrix()
    h = 1e-5
    S_inv = [decompose(M1 + s * M1d, M2 + s * M2d, _at(g1, g2, xi1, xi2, s)).S_inv for s in (-h, h)]
    d = decompose(M1, M2, g1.inverse() * g2)
    assert _rel(d.S_inv_rate(xi2 - d.Ad12_inv @ xi1, M1d, M2d), (S_inv[1] - S_inv[0]) / (2 * h)) < 1e-8


@pytest.mark.parametrize("seed", SEEDS[:4])
def test_n_body_two_equals_pair(seed):
    M1, M2, g1, g2, xi1, xi2 = _case(seed)
    g12 = g1.inverse() * g2
    d, n = decompose(M1, M2, g12), decompose_n([M1, M2], [g12])
    assert _rel(n.S, d.S) < 1e-14 and _rel(n.S_inv, d.S_inv) < 1e-14 and _rel(n.M_tot, d.M_tot) < 1e-14
    V_L, V_Es = n.locked_shape([xi1, xi2])
    P_L, P_E = d.locked_shape(xi1, xi2)
    assert _rel(V_L, P_L) < 1e-14 and _rel(V_Es[0], P_E) < 1e-14


@pytest.mark.parametrize("seed", SEEDS[:4])
def test_n_body_three(seed):
    pin.seed(seed)
    rng = np.random.default_rng(seed)
    Ms = [pin.Inertia.Random().matrix() for _ in range(3)]
    gs = [pin.SE3.Random() for _ in range(3)]
    xis = [rng.normal(size=6) for _ in range(3)]
    n = decompose_n(Ms, [gs[0].inverse() * g for g in gs[1:]])
    assert _rel(n.S @ n.S_inv, np.eye(18)) < 1e-12
    Ms_ = n.M_star
    # the locked system is decoupled from the shapes (the shapes couple among themselves: see the next test)
    assert np.linalg.norm(Ms_[:6, 6:]) < 1e-12 * np.linalg.norm(Ms_)
    assert np.linalg.norm(Ms_[6:, :6]) < 1e-12 * np.linalg.norm(Ms_)
    assert _rel(Ms_[:6, :6], n.M_tot) < 1e-12
    V_L, V_Es = n.locked_shape(xis)
    for i in (1, 2):  # each shape twist is the body twist of g1⁻¹ g_i
        h = 1e-5
        fd = pin.log6(_at(gs[0], gs[i], xis[0], xis[i], -h).inverse() * _at(gs[0], gs[i], xis[0], xis[i], h)).vector / (2 * h)
        assert _rel(V_Es[i - 1], fd) < 1e-8
    H_world = sum(g.dualAction @ M @ xi for g, M, xi in zip(gs, Ms, xis))
    assert _rel(n.M_tot @ V_L, gs[0].toActionMatrix().T @ H_world) < 1e-12
    assert _rel(n.momentum(xis), n.M_tot @ V_L) < 1e-12
    V = np.concatenate([V_L, *V_Es])
    assert 0.5 * V @ Ms_ @ V == pytest.approx(sum(0.5 * x @ M @ x for x, M in zip(xis, Ms)), rel=1e-12)
    back = n.body_twists(V_L, V_Es)
    assert all(_rel(a, b) < 1e-12 for a, b in zip(back, xis))
    with pytest.raises(ValueError):
        decompose_n(Ms[:1], [])


def test_pair_decomposition_is_frozen():
    M1, M2, g1, g2, *_ = _case(0)
    d = decompose(M1, M2, g1.inverse() * g2)
    assert isinstance(d, PairDecomposition)
    with pytest.raises(AttributeError):
        d.M_tot = np.eye(6)


def test_three_masses_on_a_line_shapes_couple():
    """n = 3 point masses along x: locked inertia Σm; the shape block in (ẋ2 − ẋ1, ẋ3 − ẋ1) is
    [[m2 − m2²/M, −m2 m3/M], [−m2 m3/M, m3 − m3²/M]] (M = Σm), from ½Σ m_i ẋ_i² with ẋ1 = v_L − (m2 e2 + m3 e3)/M.
    So M* of (5.13) is block-diagonal between locked and shape, not between the shapes."""
    m = (3.0, 7.0, 2.0)
    Y = lambda mi: pin.Inertia(mi, np.zeros(3), 1e-6 * np.eye(3)).matrix()
    gs = [pin.SE3(np.eye(3), np.array([x, 0, 0])) for x in (1.0, 4.5, -2.0)]
    Ms_ = decompose_n([Y(mi) for mi in m], [gs[0].inverse() * g for g in gs[1:]]).M_star
    M = sum(m)
    assert Ms_[0, 0] == pytest.approx(M, rel=1e-14)
    assert Ms_[6, 6] == pytest.approx(m[1] - m[1] ** 2 / M, rel=1e-12)
    assert Ms_[12, 12] == pytest.approx(m[2] - m[2] ** 2 / M, rel=1e-12)
    assert Ms_[6, 12] == pytest.approx(-m[1] * m[2] / M, rel=1e-12)
