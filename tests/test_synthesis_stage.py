"""The synthesize stage end to end: CLI exit codes and messages, gains.yaml, results.json, and the
pulsar_simple guarantees checked against an independent closed-loop simulation (scipy solve_ivp)."""

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from sms_cli.cli import app

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "tests" / "data"

HUB = """name: hub_wheels
robot:
  urdf: hub_hinge.urdf
  arm_joints: []
springs:
  - {{joint: hinge, stiffness: 20 N m/rad, damping: 0.1}}
wheels:
  arrays:
    - {{name: rw, layout: orthogonal, mount: hub, max_torque: 0.05 N m, max_speed: 6000 rpm,
       spin_inertia: 0.01 kg m^2, mass: 0}}
synthesis:
  law: lmi
  lmi:
    controller_region: {{decay_rate: {decay} rad/s, min_damping: 0.5, max_frequency: {radius} rad/s}}
    observer_region: {{decay_rate: 0.01 rad/s, max_frequency: 50 rad/s}}
    sampling: {{samples: 0}}
    tracking_error_amplitude: 0.1
"""


def hub_mission(tmp_path, decay, radius):
    shutil.copy(DATA / "hub_hinge.urdf", tmp_path / "hub_hinge.urdf")
    p = tmp_path / "hub.yaml"
    p.write_text(HUB.format(decay=decay, radius=radius))
    return p


def test_decay_beyond_wheel_authority_fails_with_exit_3_through_the_cli(tmp_path):
    # wheel 0.05 N m on 0.01 kg m² → a = 5 rad/s²; a 0.1 rad tracking error at k_p ≥ α² = 100 1/s²
    # needs 10 rad/s²: infeasible, and the message names the groups in conflict and the fix
    m = hub_mission(tmp_path, decay=10, radius=20)
    r = CliRunner().invoke(app, ["synthesize", str(m), "-o", str(tmp_path / "out")])
    assert r.exit_code == 3, r.output
    assert "LMI synthesis infeasible" in r.output
    assert "'actuator_authority'" in r.output and "'controller_region'" in r.output
    assert "lower decay_rate" in r.output
    assert "Traceback" not in r.output
    sec = json.loads((tmp_path / "out" / "results.json").read_text())["synthesis"]
    assert sec["status"] == "infeasible"


def test_feasible_request_writes_verified_gains(tmp_path):
    m = hub_mission(tmp_path, decay=0.5, radius=5)
    out = tmp_path / "out"
    r = CliRunner().invoke(app, ["synthesize", str(m), "-o", str(out), "--json"])
    assert r.exit_code == 0, r.output
    sec = json.loads(r.output)
    assert sec["verification"]["passed"] and sec["status"] == "verified"
    from sms_cli.synthesis.gains_io import read_gains

    g = read_gains(out / "gains.yaml")
    assert g.law == "lmi" and g.actuators == ["rw1", "rw2", "rw3"]
    assert g.controller.units == "acceleration"
    # the poles of s² + k_v s + k_p (recomputed here) are in the requested region
    for kp, kv in zip(g.controller.kp, g.controller.kv):
        s = np.roots([1.0, kv, kp])
        assert np.all(-s.real >= 0.5 * (1 - 1e-6)) and np.all(np.abs(s) <= 5 * (1 + 1e-6))
        assert np.all(-s.real / np.abs(s) >= 0.5 * (1 - 1e-6))
    assert (out / "synthesis_poles.png").stat().st_size > 1000
    assert sec["worst_cost"]["gramian"] < sec["gamma"] ** 2


def test_pd_through_the_stage_gives_bandwidth_on_worst_inertia(tmp_path):
    from sms_cli.mission.load import load_mission
    from sms_cli.model import compile_system
    from sms_cli.synthesis.build import locked_inertia, workspace_configurations
    from sms_cli.synthesis.stage import run_synthesis

    p = tmp_path / "pd.yaml"
    p.write_text(f"extends: {ROOT / 'missions' / 'caldera_s1_slew.yaml'}\nname: pd\n"
                 "synthesis:\n  law: pd\n  pd: {bandwidth: 0.2 rad/s, damping: 0.8}\n"
                 "  workspace: {samples: 8, spread: 0.5, seed: 1}\n")
    loaded = load_mission(p)
    sec = run_synthesis(loaded, tmp_path / "out", plots=False)
    assert sec["verification"]["passed"]
    # independent oracle: the locked inertia of every sampled configuration, from the mass matrix
    sm = compile_system(loaded)
    qs = workspace_configurations(sm, loaded.mission.synthesis)
    J = np.array([np.diag(locked_inertia(sm, q)) for q in qs])
    kp = np.array([g["kp_n_m_rad"] for g in sec["gains"]])
    kd = np.array([g["kd_n_m_s_rad"] for g in sec["gains"]])
    k = np.argmax(J, axis=0)
    for i in range(3):
        s = np.roots([J[k[i], i], kd[i], kp[i]])
        np.testing.assert_allclose(np.abs(s), 0.2, rtol=1e-9)
        np.testing.assert_allclose(-s.real / np.abs(s), 0.8, rtol=1e-9)


def test_shipped_smc_missions_synthesise(tmp_path):
    from sms_cli.mission.load import load_mission
    from sms_cli.synthesis.classical import twisting_ok
    from sms_cli.synthesis.gains_io import read_gains
    from sms_cli.synthesis.stage import run_synthesis

    for name in ("caldera_s1_slew", "astrobee_arm"):
        path = ROOT / "missions" / f"{name}.yaml"
        assert path.exists(), f"{name} is a shipped mission"
        sec = run_synthesis(load_mission(path), tmp_path / name, plots=False)
        assert sec["verification"]["passed"], sec["verification"]
        g = read_gains(tmp_path / name / "gains.yaml")
        assert g.simulation["attitude"]["law"] in ("smc", "twisting_smc")
        if g.smc.twisting is not None:
            t = g.smc.twisting
            assert twisting_ok(t.C, t.K_m, t.K_M, t.r1, t.r2)
        else:
            # c J_min dominates the disturbance bound with the requested margin
            Jmin = np.array(sec["inertia"]["min_kg_m2"])
            np.testing.assert_allclose(np.array(g.smc.c) * Jmin, 1.5 * np.array(g.smc.disturbance_bound), rtol=1e-9)


@pytest.mark.slow
def test_pulsar_simple_poles_and_gamma_against_simulation(tmp_path):
    """K, L of pulsar_simple: poles in the region at every linearisation, and ∫ε_cᵀε_c < γ² for
    initial observer errors on the boundary of E (and the tracking-box corners), by integrating
    the linear closed loop of the reduced model (Kraiem 2022 (3.41)) with scipy's solve_ivp."""
    from scipy.integrate import solve_ivp

    from sms_cli.mission.load import load_mission
    from sms_cli.model import compile_system
    from sms_cli.synthesis.build import lmi_setup
    from sms_cli.synthesis.gains_io import read_gains
    from sms_cli.synthesis.stage import run_synthesis

    loaded = load_mission(ROOT / "missions" / "pulsar_simple.yaml")
    assert loaded.mission.synthesis is not None, "the flagship mission has a synthesis section"
    sec = run_synthesis(loaded, tmp_path, plots=False)
    g = read_gains(tmp_path / "gains.yaml")
    req = lmi_setup(compile_system(loaded), loaded.mission.synthesis).request
    kp, kv, L = np.array(g.controller.kp), np.array(g.controller.kv), np.array(g.observer.L)
    gamma = sec["gamma"]
    n_q = len(kp)
    rng = np.random.default_rng(3)
    for m in req.linearisations():
        ec = np.concatenate([np.roots([1.0, kv[i], kp[i]]) for i in range(n_q)])
        eo = np.linalg.eigvals(m.A_e - L @ m.C_e)
        assert np.all(req.controller_region.contains(ec)), m.label
        assert np.all(req.observer_region.contains(eo)), m.label
        n_e = m.n_e
        A = np.zeros((2 * n_q + n_e + 1, 2 * n_q + n_e + 1))
        A[:n_q, n_q:2 * n_q] = np.eye(n_q)
        A[n_q:2 * n_q, :n_q] = -np.diag(kp)
        A[n_q:2 * n_q, n_q:2 * n_q] = -np.diag(kv)
        A[n_q:2 * n_q, 2 * n_q:2 * n_q + n_e] = m.B_eps
        A[2 * n_q:2 * n_q + n_e, 2 * n_q:2 * n_q + n_e] = m.A_e - L @ m.C_e

        def f(t, w):
            d = A @ w
            d[-1] = float(w[:n_q] @ w[:n_q])  # ∫ε_cᵀε_c as an extra state
            return d

        w = np.linalg.cholesky(np.linalg.inv(req.E_e))
        for _ in range(3):
            x = rng.normal(size=n_e)
            e0 = w @ (x / np.linalg.norm(x))  # on the boundary of εᵀEε = 1
            z0 = np.concatenate([req.tracking[:, 0] * rng.choice([-1, 1], n_q), np.zeros(n_q)])
            t_end = 40.0 / max(req.observer_region.alpha, 1e-3)
            sol = solve_ivp(f, (0, min(t_end, 4000.0)), np.concatenate([z0, e0, [0.0]]), method="DOP853",
                            rtol=1e-8, atol=1e-12)
            assert sol.success
            assert sol.y[-1, -1] < gamma**2, (m.label, sol.y[-1, -1], gamma**2)
