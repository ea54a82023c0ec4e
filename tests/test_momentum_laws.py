"""The momentum-based Lyapunov laws of Vicariotto 2023 ch. 4 (sms_cli.sim.laws.momentum) along simulated
trajectories (tests/data/momentum_*.yaml: Basilisk's hub, three wheels along x, y, z, 5 degrees about each
axis, control rate = 1/dt so the law is sampled at every plant step).

The bound. W_k is the law's W on the state after plant step k (``Simulation.lyapunov_series``), D_k the
dissipation the proof gives (−Ẇ: θ̇ᵀK_dθ̇, μᵀK_d^bμ + θ̇ᵀK_d^wθ̇ + ċᵀK_dċ, ωᵀK_dω + ċᵀK_dċ; task 2 of the hierarchical law less
its μ ≠ 0 residual power). The RKMK4 step and the zero-order hold of the law over the step make
r_k = W_{k+1} − W_k + ½(D_k + D_{k+1})dt nonzero: measured max_k |r_k| = O(dt²) and Σ|r_k| = O(dt) (the hold
is first order), so

- Σ_k |r_k| ≤ 0.03 max W at dt = 0.1 s and halves (ratio in [1.6, 2.5]) at dt = 0.05 s;
- the largest one-step increase of W, max_k (W_{k+1} − W_k), is ≤ 1e-6 max W at dt = 0.1 s and, when positive,
  drops by at least 8 at dt = 0.05 s (measured 16, ≈ 2⁴; the two free-floating laws; the free-flying and
  hierarchical and SE(3) PD W never increase at these steps).
"""

from __future__ import annotations

import functools

import numpy as np
import pytest

from conftest import ROOT

from sms_cli.mission.load import load_mission
from sms_cli.model import compile_system
from sms_cli.sim.engine import Simulation

DATA = ROOT / "tests" / "data"
CASES = ["momentum_ff_wheels", "momentum_shaping", "momentum_free_flying", "momentum_hierarchical", "momentum_se3_pd",
         "momentum_quaternion"]


@functools.lru_cache(maxsize=None)
def run(name: str, dt: float):
    loaded = load_mission(DATA / f"{name}.yaml")
    sm = compile_system(loaded)
    # the Python loop keeps the series (the compiled loop's equals it: tests/test_compiled_momentum.py)
    spec = loaded.mission.simulation.model_copy(update={"dt": dt, "control_rate": 1.0 / dt, "engine": "python"})
    sim = Simulation(sm, spec, progress=False)
    assert not sim.compiled_loop
    result = sim.run()
    assert result.status == "completed"
    L = sim.lyapunov_series
    W = np.array([d["W"] for _, _, d in L])
    D = np.array([d["dissipation"] - d.get("residual", 0.0) for _, _, d in L])
    stage = np.array([d.get("stage", 1.0) for _, _, d in L])
    same = np.diff(stage) == 0
    r = (np.diff(W) + 0.5 * (D[1:] + D[:-1]) * dt)[same]
    inc = np.diff(W)[same]
    return sim, result, W, r, inc


@pytest.mark.parametrize("name", CASES)
def test_w_follows_its_dissipation_to_the_integration_error(name):
    _, _, W, r1, _ = run(name, 0.1)
    _, _, _, r2, _ = run(name, 0.05)
    s1, s2 = np.abs(r1).sum(), np.abs(r2).sum()
    assert s1 <= 0.03 * W.max()
    assert 1.6 <= s1 / s2 <= 2.5


@pytest.mark.parametrize("name", CASES)
def test_w_never_increases_beyond_the_integration_error(name):
    sim, result, W, _, i1 = run(name, 0.1)
    _, _, _, _, i2 = run(name, 0.05)
    assert i1.max() <= 1e-6 * W.max()
    if i1.max() > 0:
        assert i2.max() <= i1.max() / 8
    assert result.overall["lyapunov_increase_max"] == max(i1.max(), 0.0)
    assert W[-1] < 1e-4 * W.max()
    assert result.phases[0]["lyapunov_start"] == W[0] and result.phases[0]["lyapunov_end"] == W[-1]


@pytest.mark.parametrize("name", CASES)
def test_each_law_converges(name):
    sim, result, _, _, _ = run(name, 0.1)
    assert result.overall["attitude_error_deg"]["final"] < 0.05
    end = sim.lyapunov_series[-1][2]
    assert end.get("locked", end.get("rotation")) < 1e-6  # ½ μᵀIμ (½ ωᵀ(I − GJGᵀ)ω for se3_pd)
    if name in ("momentum_free_flying", "momentum_se3_pd", "momentum_quaternion"):  # the CoM is back at its first-tick position, at rest
        assert sim.lyapunov_series[-1][2]["translation"] < 1e-4 * sim.lyapunov_series[0][2]["translation"]


@pytest.mark.parametrize("name", ["momentum_ff_wheels", "momentum_shaping"])
def test_free_floating_keeps_zero_momentum(name):
    _, result, _, _, _ = run(name, 0.1)
    assert result.conservation["angular_momentum_drift_rel"] <= 1e-12
    assert result.conservation["linear_momentum_drift_abs"] <= 1e-12


def test_shaping_settles_faster_than_plain_free_floating_at_equal_wheel_gains():
    """Inertia shaping with the plain law's gains: the stiffness enters without Λᵀ (Vicariotto 2023 L776-L784)."""
    from sms_cli.sim.laws.momentum import WheelsFreeFloating

    loaded = load_mission(DATA / "momentum_ff_wheels.yaml")
    sm = compile_system(loaded)
    plain = WheelsFreeFloating(sm, 81.0, 3.0e-6)
    shaped = WheelsFreeFloating(sm, 81.0, 3.0e-6, inertia_shaping=True)
    from sms_cli.sim.interfaces import AttitudeRef, Sensed

    q = sm.q0.copy()
    s = Sensed(0.0, q[3:7], np.zeros(3), q[:3], np.zeros(3), np.zeros(0), np.zeros(0), np.zeros(3), q, sm.v0 * 0)
    ref = AttitudeRef(np.array([0.0, 0.0, 0.0, 1.0]))
    tp, _ = plain.actuate(s, ref)
    ts, _ = shaped.actuate(s, ref)
    ls = plain._ls
    assert np.allclose(tp, ls.Lambda.T @ shaped.actuate(s, ref)[0], rtol=1e-9)  # γ vs Λᵀγ at θ̇ = 0
    assert np.linalg.norm(ts) > 1e3 * np.linalg.norm(tp)


def test_compiled_loop_takes_the_momentum_laws_and_wrench_laws_need_free_flying():
    from sms_cli.errors import InputError

    loaded = load_mission(DATA / "momentum_free_flying.yaml")
    sm = compile_system(loaded)
    spec = loaded.mission.simulation
    sim = Simulation(sm, spec, progress=False)
    assert sim.compiled_unsupported() is None and sim.compiled_loop
    phases = [p.model_copy(update={"base_mode": "rotation-free-floating"}) for p in spec.phases]
    with pytest.raises(InputError):
        Simulation(sm, spec.model_copy(update={"phases": phases}), progress=False)


# ---------------------------------------------------------------------------- the exact Ẇ at one state
def _w_dot(name: str, attitude, omega, wheel_rates, lin_vel=(0.0, 0.0, 0.0), com_error=(0.0, 0.0, 0.0), stage=1,
           ref_rpy=(0.0, 0.0, 0.0)):
    """(Ẇ by a central difference along the exact flow of the plant under the law's command, −D of the proof)."""
    import pinocchio as pin

    from sms_cli.sim.interfaces import AttitudeRef, Sensed
    from sms_cli.sim.laws import build_attitude_law

    loaded = load_mission(DATA / f"{name}.yaml")
    sm = compile_system(loaded)
    law = build_attitude_law(loaded.mission.simulation.attitude, sm)
    q = sm.q0.copy()
    q[3:7] = pin.Quaternion(pin.rpy.rpyToMatrix(*attitude)).coeffs()
    v = np.zeros(sm.nv)
    v[3:6] = omega
    v[sm.idx.wheels] = wheel_rates
    v[:3] = lin_vel
    ref = AttitudeRef(np.asarray(pin.Quaternion(pin.rpy.rpyToMatrix(*ref_rpy)).coeffs()))
    if hasattr(law, "stage"):
        law.stage = stage
    if hasattr(law, "target"):
        law.target = pin.centerOfMass(sm.model, sm.data, q) - np.asarray(com_error)
    s = Sensed(0.0, q[3:7], v[3:6], q[:3], np.zeros(3), np.zeros(0), np.zeros(0), v[sm.idx.wheels], q, v)
    tw, wrench = law.actuate(s, ref)
    tau = np.zeros(sm.nv)
    tau[sm.idx.wheels] = tw
    if wrench is not None:
        tau[:6] = wrench

    def flow(h):
        # second-order Taylor step of (q, v) under the constant command: W(h) to O(h³)
        a0, _ = sm.forward_dynamics(q, v, np.zeros(0), np.zeros(0), tau)
        qh = pin.integrate(sm.model, q, v * h + 0.5 * a0 * h * h)
        vh = v + a0 * h
        return law.lyapunov_terms(qh, vh, ref.quat)["W"]

    h = 1e-4
    d = law.lyapunov_terms(q, v, ref.quat)
    return (flow(h) - flow(-h)) / (2 * h), -(d["dissipation"] - d.get("residual", 0.0))


STATE = dict(attitude=(1.2, -0.7, 2.0), omega=(0.05, -0.04, 0.08), wheel_rates=(-400.0, 500.0, 200.0))  # Λθ̇ not along ω


@pytest.mark.parametrize("name,stage", [("momentum_free_flying", 1), ("momentum_hierarchical", 1),
                                        ("momentum_hierarchical", 2), ("momentum_se3_pd", 1), ("momentum_offset", 1),
                                        ("momentum_quaternion", 1)])
def test_w_dot_is_minus_the_dissipation_at_a_tumbling_state(name, stage):
    """Large rotation, spin and wheel rates: every coupling term of (4.15)/(4.16) counts (|Λθ̇| ~ 0.05 rad/s);
    task 2 of the hierarchical law with its μ ≠ 0 residual power; momentum_offset: the CoM 0.37 m off the base
    origin, where the wrench about the origin needs the lever c_b × f."""
    translates = name in ("momentum_free_flying", "momentum_se3_pd", "momentum_offset", "momentum_quaternion")
    extra = dict(lin_vel=(0.3, -0.2, 0.1), com_error=(1.0, -2.0, 0.5)) if translates else {}
    wdot, expected = _w_dot(name, **STATE, **extra, stage=stage)
    assert abs(wdot - expected) <= 1e-8 * abs(expected)


@pytest.mark.parametrize("name", ["momentum_free_flying", "momentum_se3_pd", "momentum_quaternion"])
def test_w_dot_with_a_turned_reference(name):
    """The error is taken in the body frame (R_e = R_dᵀR, q_ref⁻¹ ⊗ q): with a reference away from the identity
    a world-frame error would break Ẇ = −D."""
    extra = dict(lin_vel=(0.3, -0.2, 0.1), com_error=(1.0, -2.0, 0.5))
    wdot, expected = _w_dot(name, **STATE, **extra, ref_rpy=(0.4, -0.3, 1.1))
    assert abs(wdot - expected) <= 1e-8 * abs(expected)


def test_w_dot_of_the_free_floating_laws_at_zero_momentum():
    """(4.13) and §4.2.2 at μ = 0 (ω = −Λθ̇), a large attitude error: Ẇ = −θ̇ᵀK_dθ̇ exactly."""
    from sms_cli.dynamics.locked import locked_shape

    loaded = load_mission(DATA / "momentum_ff_wheels.yaml")
    sm = compile_system(loaded)
    wd = np.array([400.0, -300.0, 500.0])
    omega = -locked_shape(sm, sm.q0).Lambda @ wd
    for name in ("momentum_ff_wheels", "momentum_shaping"):
        wdot, expected = _w_dot(name, STATE["attitude"], omega, wd)
        assert abs(wdot - expected) <= 1e-8 * abs(expected)


# ---------------------------------------------------------------------------- sms synthesize (synthesis.pd.target_law)
@pytest.mark.parametrize("target,data", [("wheels_free_floating", "momentum_ff_wheels"), ("inertia_shaping", "momentum_shaping"),
                                         ("free_flying", "momentum_free_flying"), ("se3_pd", "momentum_se3_pd")])
def test_synthesized_gains_are_the_hand_derived_ones(target, data):
    """K_p = I ω_n², K_d = 2ζω_n I per axis, mapped through Λ = J/I (sms_cli.synthesis.stage.momentum_law_gains),
    equal the gains written by hand in the test missions (ω_n = 0.3 rad/s, ζ = 0.8)."""
    from sms_cli.synthesis.stage import synthesize_mission

    loaded = load_mission(DATA / "momentum_synth.yaml")
    syn = loaded.mission.synthesis
    loaded.mission.synthesis = syn.model_copy(update={"pd": syn.pd.model_copy(update={"target_law": target})})
    block = synthesize_mission(loaded).gains.simulation["attitude"]
    hand = load_mission(DATA / f"{data}.yaml").mission.simulation.attitude.model_dump()
    for key, value in block.items():
        if key == "law" or key == "inertia_shaping":
            assert hand[key] == value
        elif key == "kd_wheels":  # 2ζω_n(ΛᵀM_θ)_ii against the hand 2ζω_n ΛJ: M_θ = J(1 − Λ)
            assert np.allclose(value, hand[key], rtol=2e-4)
        else:
            assert np.allclose(value, hand[key], rtol=1e-5), key


def test_sms_run_reads_the_synthesized_momentum_law(tmp_path):
    from conftest import run_cli

    r = run_cli("run", str(DATA / "momentum_synth.yaml"), "-o", str(tmp_path))
    assert r.exit_code == 0, r.output
    import json

    res = json.loads((tmp_path / "results.json").read_text())
    assert "wheels_free_floating" in (tmp_path / "gains.yaml").read_text()
    assert res["simulate"]["overall"]["attitude_error_deg"]["final"] < 0.05
    assert res["simulate"]["overall"]["lyapunov_increase_max"] <= 1e-6 * res["simulate"]["phases"][0]["lyapunov_start"]
