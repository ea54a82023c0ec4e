"""LMI synthesis (Kraiem 2022 Prop. 3.3.3.1 and §4.2.5) against oracles that cannot be tuned:
closed-form LQR, the exactness of single LMI regions, analytic gain bounds implied by a pole
region, the exact worst-case cost (observability Gramian) and a linear simulation."""

import numpy as np
import pytest

from sms_cli.errors import EXIT_NUMERICAL, NumericalError
from sms_cli.synthesis.lmi import (
    ErrorModel, SynthesisRequest, closed_loop, ellipsoid_from_box, lqr_lmi, synthesize,
)
from sms_cli.synthesis.reduced import ReducedIndex, error_model_at_rest
from sms_cli.synthesis.regions import PoleRegion, region_feasible
from sms_cli.synthesis.verify import verify_lmi


def toy_model(scales, n_modes=2, seed=0, coupling=0.3, label="toy"):
    """A physically shaped SPD mass matrix on [lin(3), ang(3), actuators, modes] at rest."""
    rng = np.random.default_rng(seed)
    s = np.asarray(scales, dtype=float)
    n = len(s) + n_modes
    s = np.concatenate([s, np.ones(n_modes)])
    X = rng.normal(size=(n, n))
    C = np.eye(n) + coupling * (X + X.T) / (2 * np.sqrt(n))
    w, V = np.linalg.eigh(C)
    C = V @ np.diag(np.maximum(w, 0.2)) @ V.T
    d = np.sqrt(np.diag(C))
    C = C / np.outer(d, d)
    M = np.diag(np.sqrt(s)) @ C @ np.diag(np.sqrt(s))
    n_act = len(scales) - 6
    ix = ReducedIndex(np.arange(3), np.arange(3, 6), np.arange(6, 6 + n_act), np.arange(6 + n_act, n))
    om = np.linspace(1.0, 6.0, n_modes)
    return error_model_at_rest(M, np.diag(om**2), np.diag(2 * 0.005 * om), ix, label)


def request(model, region=PoleRegion(0.3, 0.5, 5.0), obs=PoleRegion(0.3, 0.0, 20.0), **kw):
    b = [0.05] * ((model.n_e - 3) // 2) + [0.01] * 3 + [0.05] * ((model.n_e - 3) // 2)
    return SynthesisRequest([model], region, obs, ellipsoid_from_box(b), **kw)


@pytest.mark.parametrize("q1,q2,r", [(1.0, 0.0, 1.0), (4.0, 1.0, 0.5), (0.01, 0.1, 2.0)])
def test_lmi_lqr_reproduces_closed_form(q1, q2, r):
    A = np.array([[0.0, 1.0], [0.0, 0.0]])
    B = np.array([[0.0], [1.0]])
    K, P = lqr_lmi(A, B, np.diag([q1, q2]), np.array([[r]]))
    k1 = np.sqrt(q1 / r)
    np.testing.assert_allclose(K.ravel(), [k1, np.sqrt(q2 / r + 2 * k1)], rtol=2e-4)


def test_single_lmi_regions_are_exact():
    wn, ze = 2.0, 0.3  # poles −0.6 ± 1.908j
    A = np.array([[0.0, 1.0], [-wn**2, -2 * ze * wn]])
    assert region_feasible(A, PoleRegion(0.55, 0.0, 10), "decay")
    assert not region_feasible(A, PoleRegion(0.65, 0.0, 10), "decay")
    assert region_feasible(A, PoleRegion(0.1, 0.0, 2.05), "disk")
    assert not region_feasible(A, PoleRegion(0.1, 0.0, 1.95), "disk")
    assert region_feasible(A, PoleRegion(0.1, 0.28, 10), "damping")
    assert not region_feasible(A, PoleRegion(0.1, 0.32, 10), "damping")


def test_pole_placement_in_a_narrow_region_gives_the_analytic_gains():
    # poles of s² + k_v s + k_p in {Re s ≤ −α} ∩ {|s| ≤ r}  ⇒  k_v ∈ [2α, 2r], k_p ∈ [α², r²];
    # with α = 0.95 r the gains must be within 5 % (10 % for k_p) of the double pole at −r.
    r = 4.0
    m = toy_model([1e3] * 3 + [1e3] * 3 + [0.1, 2.0], n_modes=1)
    res = synthesize(request(m, region=PoleRegion(0.95 * r, 0.0, r)))
    assert np.all(res.K_v >= 2 * 0.95 * r * (1 - 1e-6)) and np.all(res.K_v <= 2 * r * (1 + 1e-6))
    assert np.all(res.K_p >= (0.95 * r) ** 2 * (1 - 1e-6)) and np.all(res.K_p <= r**2 * (1 + 1e-6))
    assert verify_lmi(request(m, region=PoleRegion(0.95 * r, 0.0, r)), res).passed


def test_ndi_observer_synthesis_is_verified():
    m = toy_model([1e3] * 3 + [2e3] * 3 + [0.13, 0.13, 50.0], n_modes=3, seed=1)
    req = request(m)
    res = synthesize(req)
    ver = verify_lmi(req, res)
    assert ver.passed, [c.detail for c in ver.failures()]
    assert ver.gramian_cost < res.gamma**2
    np.testing.assert_allclose(ver.simulated_cost, ver.gramian_cost, rtol=1e-3)
    # per-actuator structure: K = [diag(kp), diag(kv)]
    assert res.K.shape == (m.n_q, 2 * m.n_q)
    # closed loop is block triangular: its spectrum is controller ∪ observer
    A, _ = closed_loop(m, res)
    ev = np.sort_complex(np.linalg.eigvals(A))
    parts = np.concatenate([np.roots([1, res.K_v[i], res.K_p[i]]) for i in range(m.n_q)]
                           + [np.linalg.eigvals(m.A_e - res.L @ m.C_e)])
    np.testing.assert_allclose(ev, np.sort_complex(parts), atol=1e-6)


def physical_model(I_base, I_wheel, I_arm, n_modes=2, label="phys"):
    """A rigid base (mass 0.4·I_base kg, inertia I_base), 3 wheels on x/y/z, one arm joint and
    n_modes appendage modes (mass-normalised; appendage 5 % of the mass at a 2 m lever)."""
    m = 0.4 * I_base
    n = 6 + 3 + 1 + n_modes
    M = np.zeros((n, n))
    M[:3, :3] = m * np.eye(3)
    M[3:6, 3:6] = I_base * np.diag([1.0, 0.8, 0.9])
    r = np.array([0.1, 0.0, 0.05])
    rx = np.array([[0, -r[2], r[1]], [r[2], 0, -r[0]], [-r[1], r[0], 0]])
    M[:3, 3:6] = -m * rx
    M[3:6, :3] = M[:3, 3:6].T
    for k in range(3):  # wheels: spin about base x, y, z
        M[6 + k, 6 + k] = I_wheel
        M[3 + k, 6 + k] = M[6 + k, 3 + k] = I_wheel
    M[9, 9] = I_arm
    M[3:6, 9] = M[9, 3:6] = I_arm * np.array([0.0, 0.3, 0.8])
    M[:3, 9] = M[9, :3] = np.sqrt(0.01 * m * I_arm) * np.array([0.5, 0.0, 0.0])
    m_app = 0.05 * m
    for k in range(n_modes):
        i = 10 + k
        M[i, i] = 1.0
        LT = np.sqrt(m_app / n_modes) * 0.6 * np.array([1.0, 0.3 * k, 0.0])
        LR = 2.0 * LT[[1, 0, 2]]
        M[:3, i] = M[i, :3] = LT
        M[3:6, i] = M[i, 3:6] = LR
    assert np.min(np.linalg.eigvalsh(M)) > 0
    ix = ReducedIndex(np.arange(3), np.arange(3, 6), np.arange(6, 10), np.arange(10, n))
    om = np.linspace(1.0, 20.0, n_modes)
    return error_model_at_rest(M, np.diag(om**2), np.diag(2 * 0.005 * om), ix, label), np.sqrt(m_app)


def physical_request(I_base, I_wheel, I_arm, arm_authority=1.0, **kw):
    """0.2 N m wheels, a 100 N m arm joint (× arm_authority); 5 cm modal and 0.01 rad/s base-rate
    initial-error bounds (η is in sqrt(kg) m: the same deflection bound scales with the
    appendage mass)."""
    m, sqrt_mapp = physical_model(I_base, I_wheel, I_arm)
    b = [0.05 * sqrt_mapp] * 2 + [0.01] * 3 + [0.05 * sqrt_mapp] * 2
    acc = np.array([0.2 / I_wheel] * 3 + [arm_authority * 100.0 / I_arm])
    return m, SynthesisRequest([m], PoleRegion(0.2, 0.5, 2.0), PoleRegion(0.2, 0.0, 40.0), ellipsoid_from_box(b),
                               accel_limit=acc, **kw)


@pytest.mark.parametrize("I_base,I_wheel,I_arm", [(1e4, 1e-4, 1e2), (0.1, 1e-4, 1e-3), (3e3, 0.13, 50.0)])
def test_realistic_inertia_ranges_solve(I_base, I_wheel, I_arm):
    _, req = physical_request(I_base, I_wheel, I_arm)
    res = synthesize(req)
    ver = verify_lmi(req, res)
    assert ver.passed, [c.detail for c in ver.failures()]


def test_arm_authority_below_the_flexible_disturbance_is_infeasible():
    """Base and arm inertia 1e4 kg m²: the 100 N m joint gives a = 0.01 rad/s², while the worst
    initial observer error of the ellipsoid gives the arm a disturbance acceleration
    max |B_ε,arm ε_e0| = sqrt(b E⁻¹ bᵀ) = 2.24 rad/s² (224 a), and the feedback v must return the
    whole disturbance impulse (∫v dt = ∫B_εε_e dt, from ε̇_c(0) = ε̇_c(∞) = 0) while |v| ≤ a.
    Evidence that the LMI is infeasible, not ill-conditioned: the structured interior point and
    Clarabel on the unsplit LMI both find it feasible from 27× the arm's authority on (bisection
    on the arm's a: 26.9–27.6×, the same bracket for both; on the wheels' a alone: never), the
    gains verify there, and the gains synthesised without the authority constraint peak at 27.9 a
    in the worst simulated case."""
    m, req = physical_request(1e4, 0.1, 1e4)
    b = m.B_eps[3]
    assert np.sqrt(b @ np.linalg.inv(req.E_e) @ b) > 100 * req.accel_limit[3]
    with pytest.raises(NumericalError) as exc:
        synthesize(req)
    assert exc.value.exit_code == EXIT_NUMERICAL == 3
    text = exc.value.render()
    assert "LMI synthesis infeasible" in text and "'actuator_authority'" in text
    assert "raise the actuator torque limits" in text
    # the same problem with 30× the arm's torque solves and verifies (authority check included)
    _, ok = physical_request(1e4, 0.1, 1e4, arm_authority=30.0)
    res = synthesize(ok)
    ver = verify_lmi(ok, res)
    assert ver.passed, [c.detail for c in ver.failures()]
    assert [c for c in ver.checks if c.name == "actuator_authority"][0].value <= 1.0


def test_decay_rate_beyond_actuator_authority_is_infeasible_with_diagnosis():
    m = toy_model([1e3] * 3 + [1e3] * 3 + [0.1, 2.0], n_modes=1)
    # |k_p ε| ≤ a with ε = 0.1 and a = 1 ⇒ k_p ≤ 10, but Re s ≤ −α needs k_p ≥ α² = 25
    track = np.array([[0.1, 0.0], [0.1, 0.0]])
    req = request(m, region=PoleRegion(5.0, 0.0, 8.0), accel_limit=np.array([1.0, 1.0]), tracking=track)
    with pytest.raises(NumericalError) as exc:
        synthesize(req)
    e = exc.value
    assert e.exit_code == EXIT_NUMERICAL == 3
    text = e.render()
    assert "LMI synthesis infeasible" in text
    assert "'controller_region'" in text and "'actuator_authority'" in text
    assert "lower decay_rate" in text
    # a request well within authority (α² ε = 0.001 ≪ 1) is feasible, and the peak feedback
    # acceleration of the worst simulated case stays below the limit
    ok = request(m, region=PoleRegion(0.1, 0.0, 1.0), accel_limit=np.array([1.0, 1.0]), tracking=track)
    res = synthesize(ok)
    ver = verify_lmi(ok, res)
    assert ver.passed, [c.detail for c in ver.failures()]


def sampled_request(relaxation, step, nominal_seeds=(4, 5)):
    """Two linearisations; three samples near the first (mass-matrix coupling 0.3 + k·step)."""
    base = [1e3] * 3 + [2e3] * 3 + [0.13, 20.0]
    nominal = [toy_model(base, n_modes=2, seed=s, label=f"lin{s}") for s in nominal_seeds]
    samples = [toy_model(base, n_modes=2, seed=4, coupling=0.3 + step * k, label=f"s{k}") for k in range(1, 4)]
    b = [0.05, 0.05, 0.01, 0.01, 0.01, 0.05, 0.05]
    return SynthesisRequest(nominal, PoleRegion(0.3, 0.5, 5.0), PoleRegion(0.3, 0.0, 20.0),
                            ellipsoid_from_box(b), samples=samples, relaxation=relaxation)


@pytest.mark.parametrize("relaxation,step", [("scaled", 0.002), ("thesis", 0.0002)])
def test_several_linearisations_and_sampled_relaxation(relaxation, step):
    """ρ relaxations: the gains hold the poles in the regions and the returned P certifies γ at
    every sample (verify: eigenvalues and the dissipation inequality at each sample, not the
    solver's word). 'thesis' needs samples ten times closer (see the module doc of lmi.py)."""
    req = sampled_request(relaxation, step)
    res = synthesize(req)
    assert res.rho[0][0] > 0 and res.rho[0][1] > 0 and res.rho[1] == (0.0, 0.0)
    ver = verify_lmi(req, res)
    assert ver.passed, (relaxation, [c.detail for c in ver.failures()])
    cert = [c for c in ver.checks if c.name == "certificate"][0]
    assert "over 5 linearisation(s)" in cert.detail
    # a norm ball around the samples is a larger set than their convex hull: γ is not below
    # the polytopic one
    poly = synthesize(sampled_request("polytopic", step))
    assert res.gamma >= poly.gamma * (1 - 1e-3)


def _observer_radius(A, C, G, N, P_max=None, region=None):
    """Independent SDP on constraints of the observer alone (necessary for the robust LMI).
    P_max None: largest ρ with [[(PA − WC)^s + ρ²NᵀN, PG], [GᵀP, −I]] ≺ 0 (Petersen, δ = 1 by
    homogeneity): the quadratic stability radius of the best observer for ΔA = GΔN.
    Otherwise: largest ρ with (PA − WC)^s + ρI ≺ 0, P ⪯ P_max and the observer region LMIs on
    (P, W) (the printed (3.52) block with the other observer constraints of the LMI)."""
    import cvxpy as cp

    from sms_cli.synthesis.regions import region_lmis

    n = A.shape[0]
    P = cp.Variable((n, n), symmetric=True)
    W = cp.Variable((n, C.shape[0]))
    t = cp.Variable()
    PA = P @ A - W @ C
    cons = [P >> 1e-9 * np.eye(n)]
    if P_max is not None:
        cons += [PA + PA.T + t * np.eye(n) << 0, P << P_max] + region_lmis(cp, PA.T, P, region, 0.0)
        cp.Problem(cp.Maximize(t), cons).solve(solver=cp.CLARABEL)
        return float(t.value)
    k = G.shape[1]
    M = cp.bmat([[PA + PA.T + N.T @ N, P @ G], [G.T @ P, -t * np.eye(k)]])  # ρ² = 1/t
    cons.append((M + M.T) / 2 << 0)
    cp.Problem(cp.Minimize(t), cons).solve(solver=cp.CLARABEL)
    return float(1 / np.sqrt(t.value))


def test_robust_lmi_necessary_conditions_on_the_sampled_case():
    """Why the relaxations have their form (module doc of lmi.py), on the samples of
    test_several_linearisations_and_sampled_relaxation at step 0.002, in the solver's scaled
    coordinates. The observer block of the robust LMI alone is a necessary condition:
    - unstructured ΔA_e (the first 'scaled'): the best observer tolerates ρ₁ ≈ 0.0022 < the
      sampled σ̄(ΔA_e) = 0.014, so that LMI is infeasible for any gains;
    - relative ΔA_e = GΔN (the current 'scaled'): radius ≈ 0.006 > the sampled ρ₁ = 0.0033;
    - printed (3.52): (PA − WC)^s + (ρ₁ + ρ₂)I ≺ 0 with P ⪯ E_e and the observer region holds
      only up to 0.0101 < the printed ρ₁ + ρ₂ = 2·0.014 + 0.035 (scale dependent: without the
      region's disk, which bounds L, it would be 0.36), and synthesize reports the robustness group."""
    from sms_cli.synthesis.lmi import _rho, _scale

    req = sampled_request("scaled", 0.002)
    sc = _scale(req)
    m = sc.models[0]
    A, C, n = m.A_e, m.C_e, m.n_e
    dA = max(np.linalg.norm(s.A_e - A, 2) for s in sc.samples)
    assert _observer_radius(A, C, np.eye(n), np.eye(n)) < 0.25 * dA
    rows = np.flatnonzero(np.max([np.abs(s.A_e - A).max(axis=1) for s in sc.samples], axis=0) > 1e-12)
    rho1 = _rho(sc, "scaled")[0][0]
    assert _observer_radius(A, C, np.eye(n)[:, rows], A[rows]) > 1.5 * rho1
    thesis = sampled_request("thesis", 0.002)
    r1, r2 = _rho(_scale(thesis), "thesis")[0]
    Ee = np.diag(sc.T) @ req.E_e @ np.diag(sc.T)
    bound = _observer_radius(A, C, None, None, P_max=Ee, region=req.observer_region.scaled(sc.omega_c))
    assert bound < 0.25 * (r1 + r2)
    with pytest.raises(NumericalError) as exc:
        synthesize(thesis)
    assert "'robustness'" in exc.value.render()


def test_chapter4_ndo_variant_is_verified():
    m = toy_model([1e3] * 3 + [2e3] * 3 + [0.13, 20.0], n_modes=2, seed=6)
    b = [0.05, 0.05, 0.01, 0.01, 0.01, 0.05, 0.05]
    req = SynthesisRequest([m], PoleRegion(0.3, 0.5, 5.0), PoleRegion(0.3, 0.0, 20.0), ellipsoid_from_box(b),
                           variant="ndi_observer_ndo", E_d=ellipsoid_from_box([0.01, 0.5]))
    res = synthesize(req)
    assert res.Q_d is not None and np.all(np.linalg.eigvalsh(res.Q_d) > 0)
    ver = verify_lmi(req, res)
    assert ver.passed, [c.detail for c in ver.failures()]
    names = [c.name for c in ver.checks]
    assert "ndo_poles" in names and "certificate" in names


def test_polytopic_robustness_over_sampled_linearisations():
    """The alternative to (3.51)-(3.52): every sample is one more vertex sharing P, Q, W. The
    verified poles and certificate then hold at each vertex (and, the LMIs being affine in
    (A_e, B_ε), on their convex hull: checked at the midpoint, which is not in the LMI)."""
    base = [1e3] * 3 + [2e3] * 3 + [0.13, 20.0]
    nominal = [toy_model(base, n_modes=2, seed=4, label="lin4")]
    samples = [toy_model(base, n_modes=2, seed=4, coupling=0.3 + 0.05 * k, label=f"s{k}") for k in (1, 2)]
    b = [0.05, 0.05, 0.01, 0.01, 0.01, 0.05, 0.05]
    req = SynthesisRequest(nominal, PoleRegion(0.3, 0.5, 5.0), PoleRegion(0.3, 0.0, 20.0),
                           ellipsoid_from_box(b), samples=samples, relaxation="polytopic")
    res = synthesize(req)
    ver = verify_lmi(req, res)
    assert ver.passed, [c.detail for c in ver.failures()]
    assert len(ver.poles) == 3
    mid = ErrorModel((samples[0].A_e + samples[1].A_e) / 2, samples[0].C_e, (samples[0].B_eps + samples[1].B_eps) / 2)
    eo = np.linalg.eigvals(mid.A_e - res.L @ mid.C_e)
    assert np.all(req.observer_region.contains(eo))
