"""Kraiem 2022's NDI + observer in the compiled engine: the law's kernels (``sms_cli.sim.compiled.ndi_law``)
against independent evaluations (the reduced model's formulas, the matrix exponential, Pinocchio's terms of
the SystemModel with modes), and the flagship missions (pulsar_simple, pulsar_fast_transfer; shortened, with
inline gains) run by both loops: trace, metrics and recording equal to 1e-9."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import scipy.linalg

from sms_cli.mission.load import load_mission
from sms_cli.model import compile_system
from sms_cli.sim.compiled import ndi_law as K

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def pulsar():
    return compile_system(load_mission(ROOT / "missions" / "pulsar_simple.yaml"))


def _state(sm, seed):
    rng = np.random.default_rng(seed)
    q = pin.integrate(sm.model, sm.q0, rng.normal(scale=0.3, size=sm.nv))
    return q, rng.normal(scale=0.2, size=sm.nv), rng.normal(scale=0.05, size=sm.n_modes), rng.normal(scale=0.05, size=sm.n_modes)


def _close(got, want, rel=1e-12):
    return np.abs(np.asarray(got) - np.asarray(want)).max() <= rel * max(1.0, np.abs(want).max())


def test_reduced_matrices_at_rest_equal_their_formulas(pulsar):
    """Kraiem 2022 (3.28)-(3.35) after the Routh reduction of the base translation, evaluated here with numpy."""
    sm = pulsar
    red = sm.reduced
    ix = red.ix
    for seed in range(2):
        q, _, _, _ = _state(sm, seed)
        M = sm.mass_matrix(q)
        got = red.at_rest(M)
        keep = np.concatenate([ix.base_angular, ix.actuators, ix.flexible])
        lin = ix.base_linear
        Mk = M[np.ix_(keep, keep)] - M[np.ix_(keep, lin)] @ np.linalg.inv(M[np.ix_(lin, lin)]) @ M[np.ix_(lin, keep)]
        n_q, n_f = ix.actuators.size, ix.flexible.size
        b = np.r_[0:3, 3 + n_q:3 + n_q + n_f]
        a = np.r_[3:3 + n_q]
        Mbb, Mbq, Mqq = Mk[np.ix_(b, b)], Mk[np.ix_(b, a)], Mk[np.ix_(a, a)]
        Mstar = Mbb - Mbq @ np.linalg.inv(Mqq) @ Mbq.T
        S = np.zeros((3 + n_f, 2 * n_f + 3))
        S[3:, :n_f], S[3:, n_f + 3:] = red.K_f, red.C_f
        A = np.zeros((2 * n_f + 3, 2 * n_f + 3))
        A[:n_f, n_f + 3:] = np.eye(n_f)
        A[n_f:] = -np.linalg.inv(Mstar) @ S
        Mdia = Mqq - Mbq.T @ np.linalg.inv(Mbb) @ Mbq
        Dx = -Mbq.T @ np.linalg.inv(Mbb) @ S
        assert _close(got.A_e, A, 1e-9)
        assert _close(got.M_dia, Mdia, 1e-10)
        assert _close(got.D_x, Dx, 1e-9)
        assert _close(got.B_eps, np.linalg.inv(Mdia) @ Dx, 1e-8)
        assert _close(got.B_tau[n_f:], -np.linalg.inv(Mstar) @ Mbq @ np.linalg.inv(Mqq), 1e-9)
        assert np.all(got.B_tau[:n_f] == 0) and np.all(got.C_e[:, n_f:n_f + 3] == np.eye(3))


@pytest.mark.parametrize("case", ["diagonalisable", "singular", "defective"])
def test_observer_discretisation_is_the_zoh_exponential(case):
    """Φ = e^{A T}, Γ = ∫₀ᵀ e^{A s} ds against scipy's expm of [[A, I], [0, 0]] T, on both paths of the kernel
    (eigen-decomposition; the Padé exponential for a singular or defective A)."""
    rng = np.random.default_rng(3)
    n = 7
    A = rng.normal(size=(n, n)) - 2 * np.eye(n)
    if case == "singular":
        A[:, 0] = 0.0
    elif case == "defective":
        A = np.diag(np.full(n, -0.7)) + np.diag(np.ones(n - 1), 1) * 3.0
    _assert_discretisation_is_expm(A, 0.1, 1e-12)


def _assert_discretisation_is_expm(A, T, tol, discretise=None):
    """observer_discretisation's (or ``discretise``'s) Φ, Γ equal the blocks of scipy's expm of [[A, I], [0, 0]] T to
    ``tol``."""
    n = A.shape[0]
    Phi, Gamma = np.empty((n, n)), np.empty((n, n))
    (discretise or K.observer_discretisation)(A, T, Phi, Gamma)
    aug = np.zeros((2 * n, 2 * n))
    aug[:n, :n], aug[:n, n:] = A, np.eye(n)
    E = scipy.linalg.expm(aug * T)
    assert _close(Phi, E[:n, :n], tol) and _close(Gamma, E[:n, n:], tol)


def _lightly_damped(n_modes=10, seed=5):
    """A state matrix like the flagship observer's: 3 rigid rates coupled to lightly damped modes (0.1-3 Hz, ζ 0.005),
    in random coordinates (complex pairs, a real triple)."""
    rng = np.random.default_rng(seed)
    n = 2 * n_modes + 3
    D = np.zeros((n, n))
    for k, w in enumerate(2 * np.pi * np.geomspace(0.1, 3.0, n_modes)):
        D[2 * k:2 * k + 2, 2 * k:2 * k + 2] = [[0.0, 1.0], [-w * w, -2 * 0.005 * w]]
    D[-3:, -3:] = -np.diag([0.5, 1.0, 2.0])
    P = np.eye(n) + 0.3 * rng.normal(size=(n, n))
    return P @ D @ np.linalg.inv(P)


@pytest.mark.parametrize("case", ["random", "lightly_damped", "real_spectrum"])
def test_real_blocks_are_an_eigen_decomposition(case):
    """ndi_law.real_blocks (LAPACK's real dgeev): A W = W Λ with Λ real block-diagonal, the eigenvalues of numpy's eig,
    the columns of unit-norm complex eigenvectors x ± iy; the discretisation on the flagship-like spectrum, and the
    Padé path a numba without the binding takes, against scipy's expm."""
    rng = np.random.default_rng(8)
    A = {"random": rng.normal(size=(9, 9)), "lightly_damped": _lightly_damped(),
         "real_spectrum": (lambda Q: Q @ np.diag(np.arange(1.0, 8.0)) @ np.linalg.inv(Q))(np.eye(7) + 0.2 * rng.normal(size=(7, 7)))}[case]
    n = A.shape[0]
    ok, W, re, im = K.real_blocks(A)
    assert ok
    Lam, V = np.diag(re), W.astype(complex)
    for j in np.flatnonzero(im > 0):
        Lam[j, j + 1], Lam[j + 1, j] = im[j], -im[j]
        V[:, j] = (W[:, j] + 1j * W[:, j + 1]) / np.sqrt(2.0)
        V[:, j + 1] = V[:, j].conj()
        assert im[j + 1] == -im[j]
    assert _close(W @ Lam @ np.linalg.inv(W), A, 1e-10)
    lam = re + 1j * im
    assert _close(V @ np.diag(lam) @ np.linalg.inv(V), A, 1e-10)
    assert _close(np.linalg.norm(V, axis=0), np.ones(n), 1e-13)
    want = np.linalg.eigvals(A)  # the same multiset: each of numpy's eigenvalues has one of ours within 1e-10
    assert np.abs(want[:, None] - lam[None, :]).min(axis=1).max() <= 1e-10 * np.abs(want).max()
    assert np.abs(lam[:, None] - want[None, :]).min(axis=1).max() <= 1e-10 * np.abs(want).max()
    _assert_discretisation_is_expm(A, 0.1, 1e-11)
    _assert_discretisation_is_expm(A, 0.1, 1e-11, K._discretise_by_expm)


def test_augmented_terms_equal_the_system_model(pulsar):
    """M and r = bias − internal forces of the loop (base-mounted modes) against SystemModel.mass_matrix,
    bias_forces and internal_forces (Pinocchio); the modal momenta and energy against momenta and energy."""
    from sms_cli.sim.compiled.dynamics import joint_transforms
    from sms_cli.sim.compiled.modal import modal_sample_momenta
    from sms_cli.sim.compiled.tree import flatten

    sm = pulsar
    T = flatten(sm.model)
    n = T.parent.size
    B = np.ascontiguousarray(sm.base_modal_coupling)
    om = np.concatenate([a.omega for a in sm.appendages])
    ze = np.concatenate([a.zeta for a in sm.appendages])
    for seed in range(3):
        q, v, eta, ed = _state(sm, seed)
        R, p = np.empty((n, 3, 3)), np.empty((n, 3))
        joint_transforms(T.kind, T.axis, T.place_R, T.place_p, T.idx_q, q, R, p)
        M, r = np.empty((sm.nx, sm.nx)), np.empty(sm.nx)
        K.augmented_mass(T.parent, T.kind, T.axis, T.inertia, T.armature, T.idx_v, R, p, B, M)
        K.augmented_bias(T.parent, T.kind, T.axis, T.inertia, T.idx_v, R, p, B, -(om**2), -2 * ze * om, v, eta, ed, r)
        assert _close(M, sm.mass_matrix(q))
        assert _close(r, sm.bias_forces(q, v, ed) - sm.internal_forces(q, v, eta, ed))
        out, Ms = np.empty((1, 10)), np.empty((1, sm.nx, sm.nx))
        modal_sample_momenta(T.parent, T.kind, T.axis, T.inertia, T.mass, T.com, T.armature, T.place_R, T.place_p, T.idx_q,
                             T.idx_v, B, -(om**2), q[None], v[None], eta[None], ed[None], out, Ms)
        assert _close(Ms[0], M)
        p_ref, k_com, k_origin = sm.momenta(q, v, ed)
        assert _close(out[0, :9], np.concatenate([p_ref, k_com, k_origin]))
        assert out[0, 9] == pytest.approx(sm.energy(q, v, eta, ed), rel=1e-12)


def test_actuator_dynamics_is_the_schur_complement_and_reduced_bias_needs_no_second_solve(pulsar):
    """M◇ = M_aa − M_au M_uu⁻¹ M_ua and n = r_a − M_au M_uu⁻¹ r_u (Kraiem 2022 (3.33)–(3.35)) against numpy's
    solves on the flagship's mass matrix; ``reduced_bias`` of another r at the same M (the tick's linearising
    torque) equals n of a fresh solve: the law solves M_uu once per tick."""
    sm = pulsar
    ix = sm.reduced.ix
    sets = (ix.base_linear, ix.base_angular, ix.actuators, ix.flexible)
    a, u = ix.actuators, np.r_[ix.base_linear, ix.base_angular, ix.flexible]
    rng = np.random.default_rng(11)
    for seed in range(3):
        q, *_ = _state(sm, seed)
        M = sm.mass_matrix(q)
        r, r2 = rng.normal(size=sm.nx), rng.normal(size=sm.nx)
        M_dia, n_term, sol = K.actuator_dynamics(M, r, *sets)
        Mau = M[np.ix_(a, u)]
        assert _close(M_dia, M[np.ix_(a, a)] - Mau @ np.linalg.solve(M[np.ix_(u, u)], M[np.ix_(u, a)]), 1e-10)
        assert _close(n_term, r[a] - Mau @ np.linalg.solve(M[np.ix_(u, u)], r[u]), 1e-10)
        assert _close(K.reduced_bias(sol, r2, *sets), K.actuator_dynamics(M, r2, *sets)[1], 1e-10)


def test_rotation_error_is_the_attitude_error():
    """The law's θ against ``attitude_math.attitude_error`` (rotation vector of q_ref⁻¹ ⊗ q), both signs of w."""
    from sms_cli.sim.attitude_math import attitude_error

    rng = np.random.default_rng(4)
    out = np.empty(3)
    for _ in range(20):
        q_ref, q = (x / np.linalg.norm(x) for x in rng.normal(size=(2, 4)))
        K.rotation_error(q_ref, q, out)
        assert _close(out, attitude_error(q_ref, q), 1e-13)


def test_estimated_velocity_has_zero_linear_momentum(pulsar):
    """x̂ = [v_lin; ω0; q̇_a; ḟ̂]: the measured parts as given, the observer's modal rates, and v_lin such that the
    linear momentum M_lin x̂ is zero; the first call seeds the observer's ω0 with the gyro."""
    from sms_cli.sim.compiled.ndi_law import N_FLAGS, STARTED

    sm = pulsar
    ix = sm.reduced.ix
    rng = np.random.default_rng(2)
    q, v, _, _ = _state(sm, 2)
    M = sm.mass_matrix(q)
    n_f = ix.flexible.size
    x_hat, flags, x = rng.normal(size=2 * n_f + 3), np.zeros(N_FLAGS, dtype=np.int64), np.empty(sm.nx)
    omega = v[3:6].copy()
    K.ndi_velocity(M, ix.base_linear, ix.base_angular, ix.actuators, ix.flexible, omega, v, x_hat, flags, x)
    assert flags[STARTED] == 1 and np.all(x_hat[n_f:n_f + 3] == omega)
    assert np.all(x[ix.base_angular] == omega) and np.all(x[ix.actuators] == v[ix.actuators])
    assert np.all(x[ix.flexible] == x_hat[n_f + 3:])
    assert np.abs(M[ix.base_linear] @ x).max() <= 1e-12 * np.abs(M[ix.base_linear]).max() * np.abs(x).max()


@pytest.mark.parametrize("limit", [1e9, 0.05])
def test_ndi_torques_give_the_commanded_accelerations(pulsar, limit):
    """The inversion's identity on the full dynamics M ẍ + r = [0; τ_a; 0] (any r): the arm joints accelerate
    at their commands q̈_d + kp ε + kv ε̇, and with the wheel gain kv = 0 the wheels' feedforward keeps the
    base from rotating (ω̇0 = 0). With the wheels clipped to ``limit`` the arm still gets its commands."""
    from sms_cli.sim.compiled.ndi_law import N_FLAGS, SATURATED

    sm = pulsar
    ix = sm.reduced.ix
    rng = np.random.default_rng(5)
    q, v, _, _ = _state(sm, 1)
    M = sm.mass_matrix(q)
    r = rng.normal(size=sm.nx)
    n_r, n_m = len(sm.wheels), len(sm.arm)
    na = n_r + n_m
    kp, kv = np.r_[np.zeros(n_r), rng.uniform(0.1, 1, n_m)], np.r_[np.zeros(n_r), rng.uniform(0.1, 1, n_m)]
    q_arm = q[[a.q_index for a in sm.arm]]
    ref_q, ref_qd, ref_qdd = q_arm + rng.normal(scale=0.1, size=n_m), rng.normal(size=n_m), rng.normal(size=n_m)
    flags, pinv, wrr, tau = np.zeros(N_FLAGS, dtype=np.int64), np.zeros((n_r, 3)), np.zeros(n_r), np.zeros(na)
    M_dia, n_term, sol = K.actuator_dynamics(M, r, ix.base_linear, ix.base_angular, ix.actuators, ix.flexible)
    K.ndi_command(M, M_dia, n_term, sol, ix.base_angular, ix.actuators, n_r, kp, kv, 0.3, True,
                  np.full(n_r, limit), q[3:7].copy(), v[3:6].copy(), v, q_arm, np.array([0.0, 0, 0, 1]), np.zeros(3), ref_q,
                  ref_qd, ref_qdd, flags, pinv, wrr, tau)
    rhs = -r
    rhs[ix.actuators] += tau
    xdd = np.linalg.solve(M, rhs)
    v_arm = ref_qdd + kp[n_r:] * (ref_q - q_arm) + kv[n_r:] * (ref_qd - v[ix.actuators[n_r:]])
    assert _close(xdd[ix.actuators[n_r:]], v_arm, 1e-9)
    if limit > 1:
        assert flags[SATURATED] == 0
        assert np.abs(xdd[ix.base_angular]).max() <= 1e-9 * max(1.0, np.abs(xdd).max())
    else:
        assert flags[SATURATED] == 1 and np.all(np.abs(tau[:n_r]) <= limit) and np.any(np.abs(tau[:n_r]) == limit)


def _gains(sm) -> dict:
    """Inline NDI gains for the shortened runs: the observer gain of the steady Kalman filter of the model at
    rest (a stable A − L C), joint and wheel PD gains."""
    from sms_cli.synthesis.reduced import error_model

    em = error_model(sm, sm.q0)
    n_e = em.A_e.shape[0]
    P = scipy.linalg.solve_continuous_are(em.A_e.T, em.C_e.T, 1e-2 * np.eye(n_e), 1e-4 * np.eye(3))
    L = P @ em.C_e.T / 1e-4
    return {"kp": [1.0] * 4 + [0.2] * 5, "kv": [0.7] * 4 + [0.9] * 5, "L": L.tolist()}


def _mission_text(mission: str, engine: str, phases: str, gains: dict) -> str:
    return (f"extends: {ROOT / 'missions' / mission}\nname: {Path(mission).stem}_{engine}\nsimulation:\n"
            f"  engine: {engine}\n  ndi: {json.dumps(dict(gains, attitude_gain=0.05))}\n  phases:\n{phases}")


# the flagship's phases shortened: moves small enough for the 0.2 N m wheels at this pace (no saturation), the
# tile released between them
FLAGSHIP = """    - {name: hold, kind: hold, duration: 1 s, attitude: [0, 0, 0]}
    - {name: transfer, kind: move_payload, duration: 6 s, waypoints: [{at: 3 s, joints: {rail_joint_1: 1.0e-4, arm_joint_1: 2.0e-5}},
       {at: 6 s, joints: {arm_joint_2: -2.0e-5, arm_joint_3: 1.0e-5}}]}
    - {name: release, kind: release, duration: 1 s, detach: [tile]}
    - {name: return, kind: deploy, duration: 6 s, waypoints: [{at: 3 s, joints: {arm_joint_2: 0, arm_joint_3: 0}},
       {at: 6 s, joints: {rail_joint_1: 0.5e-4, arm_joint_1: 0}}]}
    - {name: settle, kind: hold, duration: 2 s}
"""
# pulsar_fast_transfer's phases shortened: moves faster than the wheels can follow (saturation: the arm torques
# computed for the clipped wheel torques), the rail driven 1 cm past its lower stop on the way back (arrival,
# contact and release with the modal rates in the impulses)
FAST = """    - {name: hold, kind: hold, duration: 1 s, attitude: [0, 0, 0]}
    - {name: transfer, kind: move_payload, duration: 5 s, waypoints: [{at: 2.5 s, joints: {rail_joint_1: 0.1, arm_joint_1: 0.1}},
       {at: 5 s, joints: {arm_joint_2: -0.05, arm_joint_3: 0.04}}]}
    - {name: release, kind: release, duration: 1 s, detach: [tile]}
    - {name: return, kind: deploy, duration: 5 s, waypoints: [{at: 2.5 s, joints: {arm_joint_2: 0, arm_joint_3: 0}},
       {at: 5 s, joints: {rail_joint_1: -0.01, arm_joint_1: 0}}]}
    - {name: settle, kind: hold, duration: 2 s, waypoints: [{at: 1 s, joints: {rail_joint_1: 0.02}}]}
"""


@pytest.mark.parametrize("mission, phases", [("pulsar_simple.yaml", FLAGSHIP), ("pulsar_fast_transfer.yaml", FAST)])
def test_compiled_loop_equals_the_python_loop_on_the_flagship(tmp_path, pulsar, mission, phases):
    """Both loops on the flagship missions (15 DoF + 10 modes, NDI + observer, the tile released between phases):
    status, steps, metrics, conservation and every recorded message (modal coordinates, momenta with the modal
    terms, joint-stop events) equal to 1e-9; the runs exercise what they are meant to."""
    from test_compiled_arm import _compare_missions_text

    gains = _gains(pulsar)
    py, msgs = _compare_missions_text(tmp_path, lambda e: _mission_text(mission, e, phases, gains))
    sat = py["overall"]["saturation_time_s"]
    events = json.dumps([m for _, m in msgs.get("/events", [])] + [m for _, m in msgs.get("/log", [])])
    if mission == "pulsar_simple.yaml":
        assert sat == 0.0
    else:
        assert sat > 1.0 and "joint_stop" in events and "joint_stop_release" in events
    assert py["overall"]["attitude_error_rad"]["max"] > 0


def test_engine_auto_runs_the_flagship_compiled(pulsar):
    from sms_cli.sim.compiled.runner import unsupported_reason

    for mission in ("pulsar_simple.yaml", "pulsar_fast_transfer.yaml"):
        loaded = load_mission(ROOT / "missions" / mission)
        assert unsupported_reason(pulsar, loaded.mission.simulation, None) is None


def test_the_warm_up_lists_every_kernel_of_the_ndi_loop(tmp_path, pulsar):
    """After ``Simulation.warm_up`` the run compiles no new signature of the NDI loop's kernels (a cold cache
    compiles them all in the warm-up, with progress, none later in the run)."""
    import importlib

    from sms_cli.sim.engine import Simulation

    path = tmp_path / "m.yaml"
    path.write_text(_mission_text("pulsar_simple.yaml", "compiled", FLAGSHIP, _gains(pulsar)))
    loaded = load_mission(path)
    sm = compile_system(loaded)
    sim = Simulation(sm, loaded.mission.simulation, None, progress=False)
    sim.warm_up()
    kernels = {"ndi_law": ["ndi_velocity", "ndi_command", "ndi_observe", "reduced_at_rest", "observer_discretisation"],
               "ndi_loop": ["run_ticks_ndi"], "modal": ["modal_sample_momenta"], "stops": ["stop_step"], "dynamics": ["rkmk4_step"],
               "loop": ["effective_wheel_inertia"]}
    count = lambda: {f: len(getattr(importlib.import_module(f"sms_cli.sim.compiled.{m}"), f).signatures)  # noqa: E731
                     for m, fs in kernels.items() for f in fs}
    before = count()
    assert sim.run().timing["engine"] == "compiled"
    assert count() == before
