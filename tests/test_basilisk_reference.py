"""Basilisk's scenarioAttitudeFeedbackRW run by sms (missions/basilisk_rw_reference.yaml).

Without Basilisk: the compiled mass properties equal Basilisk's model (750 kg, locked inertia
diag(900, 800, 600) kg m², HR16 Js = 50 N m s / 6000 rpm), and the run obeys physics that does
not depend on the implementation:
  - the wheels are internal: total angular momentum, in Basilisk's form
    H_N = [NB](σ) (I ω + Σ Js Ω_i ĝ_i), equals its closed-form initial value throughout (1e-9 rel.);
  - each wheel is an axisymmetric rotor, so Js d(Ω_i + ĝ_iᵀω)/dt = u_i exactly: the torque
    actually applied, recovered from the state, equals the commanded one and stays within 0.2 N m;
  - once no wheel saturates, mrpFeedback's Lyapunov function V = ½ ωᵀIω + 2K ln(1 + σᵀσ) obeys
    V̇ = −P ωᵀω (the law's inertia and wheel momentum are the plant's exactly): checked step by
    step within 1 % (the zero-order hold over 0.1 s, with closed-loop time constants ≥ 20 s), and
    the attitude converges.
Both engines (the Python loop and the compiled one) run every check.
With benches/data/basilisk_reference.npz (Basilisk 2.12.1, every 10th step of
benches/basilisk_reference.py), the histories match Basilisk's at each stored second.
Tolerances: both tools integrate the same ODE between the same zero-order-hold instants with
4th-order methods (Basilisk: RK4 on MRPs; sms: RKMK4 on SE(3)); halving sms's plant step moves σ by
≤ 3e-14 and the wheel speeds by ≤ 5e-11 rad/s, and the measured differences to Basilisk are
8e-15 (σ), 6e-16 rad/s (ω), 8e-12 rad/s (Ω). The bounds below (σ 1e-10, ω 1e-11 rad/s,
Ω 1e-8 rad/s, u 1e-9 N m) keep a ≥ 100× margin for round-off on other platforms, while a
modelling slip as small as counting the wheels' inertia twice in the hub (0.02 % of I) moves σ by
9e-5 and Ω by 0.12 rad/s.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
MISSION = ROOT / "missions" / "basilisk_rw_reference.yaml"
REFERENCE = ROOT / "benches" / "data" / "basilisk_reference.npz"

I_HUB = np.array([900.0, 800.0, 600.0])  # kg m², Basilisk's IHubPntBc_B (locked, wheels included)
JS = 50.0 / (6000.0 * 2.0 * math.pi / 60.0)  # HR16 50 N m s at 6000 rpm: 1/(4π) kg m²
U_MAX = 0.2  # N m
K, P = 3.5, 30.0
SIGMA0 = np.array([0.1, 0.2, -0.3])
OMEGA0 = np.array([0.001, -0.01, 0.03])
WHEEL0 = np.array([100.0, 200.0, 300.0]) * 2.0 * math.pi / 60.0
DT = 0.1


def dcm_NB(sigma: np.ndarray) -> np.ndarray:
    """[NB] of an MRP σ_BN (Schaub & Junkins: [BN] = I + (8[σ×]² − 4(1 − σ²)[σ×])/(1 + σ²)²)."""
    s2 = float(sigma @ sigma)
    S = np.array([[0.0, -sigma[2], sigma[1]], [sigma[2], 0.0, -sigma[0]], [-sigma[1], sigma[0], 0.0]])
    return (np.eye(3) + (8.0 * S @ S - 4.0 * (1.0 - s2) * S) / (1.0 + s2) ** 2).T


class _Capture:
    """A recorder stand-in keeping every plant step's state (the engine calls due/write_step/write_event)."""

    def __init__(self):
        self.rows = []

    def due(self, t):
        return True

    def take(self, t):
        return True

    def write_step(self, t, *, transforms=None, scalars=None, force=False):
        a, r = scalars["/attitude"], scalars["/base/rate"]
        self.rows.append([t, a["qx"], a["qy"], a["qz"], a["qw"], r["x"], r["y"], r["z"],
                          *scalars["/wheels/speed"].values(), *scalars["/wheels/torque"].values()])
        return True

    def select(self, times):  # the compiled engine's block interface: every step, in blocks
        return np.arange(len(times))

    def write_block(self, times, *, transforms=None, scalars=None, relative=False):
        for i, t in enumerate(times):
            self.write_step(t, scalars={topic: {k: np.asarray(v)[i] for k, v in fields.items()}
                                        for topic, fields in scalars.items()})

    def write_event(self, *args, **kwargs):
        pass


@pytest.fixture(scope="module")
def compiled():
    from sms_cli.mission.load import load_mission
    from sms_cli.model import compile_system

    loaded = load_mission(MISSION)
    return loaded, compile_system(loaded)


@pytest.fixture(scope="module", params=["python", "compiled"])
def run(compiled, request):
    """The scenario run by each engine (every test below holds for both)."""
    from sms_cli.sim.engine import Simulation

    loaded, sm = compiled
    cap = _Capture()
    spec = loaded.mission.simulation.model_copy(update={"engine": request.param})
    result = Simulation(sm, spec, cap, progress=False).run()
    assert result.timing["engine"] == request.param
    A = np.array(cap.rows)
    q = A[:, 1:5].copy()
    q[q[:, 3] < 0] *= -1.0
    return {"result": result, "t": A[:, 0], "sigma": q[:, :3] / (1.0 + q[:, 3:4]), "omega": A[:, 5:8],
            "speeds": A[:, 8:11], "torque": A[:, 11:14]}


def test_mass_properties_are_basilisks(compiled):
    _, sm = compiled
    assert sm.total_mass == pytest.approx(750.0, abs=1e-9)
    assert np.allclose(sm.com(sm.q0), 0.0, atol=1e-12)
    H = sm.rigid_mass_matrix(sm.q0)
    assert np.allclose(H[3:6, 3:6], np.diag(I_HUB), rtol=0, atol=1e-9)  # base angular block, wheels locked
    assert [w.spin_inertia for w in sm.wheels] == pytest.approx([JS] * 3, rel=1e-12)
    assert np.allclose(np.array([w.axis for w in sm.wheels]), np.eye(3), atol=1e-15)
    # the initial attitude written as roll-pitch-yaw is σ0 exactly
    q0 = sm.q0[3:7] * (1 if sm.q0[6] >= 0 else -1)
    assert np.allclose(q0[:3] / (1 + q0[3]), SIGMA0, atol=1e-15)
    assert np.allclose(sm.v0[3:6], OMEGA0, atol=0) and np.allclose(sm.v0[sm.idx.wheels], WHEEL0, rtol=1e-15)


def test_run_completes_every_step(run):
    res = run["result"]
    assert res.status == "completed"
    assert res.steps == 6000 and run["t"].size == 6001  # the initial state is recorded too, as Basilisk's recorders do
    assert run["t"][0] == 0.0 and run["t"][-1] == pytest.approx(600.0, abs=1e-9)


def test_total_angular_momentum_is_conserved(run):
    H0 = dcm_NB(SIGMA0) @ (I_HUB * OMEGA0 + JS * WHEEL0)  # closed form at t = 0
    H = np.array([dcm_NB(s) @ (I_HUB * w + JS * W) for s, w, W in zip(run["sigma"], run["omega"], run["speeds"])])
    assert np.abs(H - H0).max() <= 1e-9 * np.linalg.norm(H0)
    k = run["result"].trace["momentum"][:, 3:6]  # the engine's own (Pinocchio) momentum, about the origin
    assert np.abs(k - H0).max() <= 1e-9 * np.linalg.norm(H0)


def test_wheel_torques_follow_the_rotor_equation_and_limits(run):
    u_cmd = run["torque"]
    assert np.abs(u_cmd).max() <= U_MAX * (1 + 1e-12)
    assert np.isclose(np.abs(u_cmd).max(), U_MAX)  # the scenario saturates the wheels at the start
    axial = run["speeds"] + run["omega"]  # Ω_i + ĝ_iᵀω with ĝ_i = body axis i
    u_applied = JS * np.diff(axial, axis=0) / DT  # over [t_k, t_k+1], recorded at t_k+1
    assert np.abs(u_applied - u_cmd[1:]).max() <= 1e-9
    assert np.abs(u_applied).max() <= U_MAX * (1 + 1e-9)


def test_lyapunov_decrease_and_convergence(run):
    sig, om, u = run["sigma"], run["omega"], run["torque"]
    V = 0.5 * np.sum(I_HUB * om**2, axis=1) + 2.0 * K * np.log1p(np.sum(sig**2, axis=1))
    saturated = np.any(np.abs(u) >= U_MAX * (1 - 1e-12), axis=1)
    last = int(np.nonzero(saturated)[0].max())
    assert 60.0 < run["t"][last] < 400.0  # saturated for a while, then not again
    dV = np.diff(V[last + 1:])
    predicted = -P * np.sum(om[last + 1:-1] ** 2, axis=1) * DT
    assert np.all(dV < 0)
    assert np.all(np.abs(dV / predicted - 1.0) < 0.01)
    angle = 4.0 * np.arctan(np.linalg.norm(sig, axis=1))
    assert angle[last] > math.radians(10)
    assert angle[-1] < math.radians(0.25)
    assert V[-1] < 1e-4 * V[last + 1]


def test_matches_basilisk_history(run):
    assert REFERENCE.exists(), f"{REFERENCE} is shipped with the repository (regenerate: benches/basilisk_reference.py)"
    ref = np.load(REFERENCE)
    kb = np.rint(ref["t"] / DT).astype(int)
    ks = np.rint(run["t"] / DT).astype(int)
    common, i_s, i_b = np.intersect1d(ks, kb, return_indices=True)
    assert common.size >= 600
    assert np.abs(run["sigma"][i_s] - ref["sigma_BN"][i_b]).max() < 1e-10
    assert np.abs(run["omega"][i_s] - ref["omega_BN_B"][i_b]).max() < 1e-11
    assert np.abs(run["speeds"][i_s] - ref["wheel_speeds"][i_b]).max() < 1e-8
    # Basilisk's torque at t_k is applied over [t_k, t_k+1]; sms records it after that step
    _, i_s2, i_b2 = np.intersect1d(ks, kb + 1, return_indices=True)
    assert np.abs(run["torque"][i_s2] - ref["wheel_torque"][i_b2]).max() < 1e-9
    assert ref["Js"] == pytest.approx([JS] * 3, rel=1e-12)
