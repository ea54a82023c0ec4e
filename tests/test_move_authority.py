"""Joint moves sized from the actuator authority (sms_cli.sim.authority, ``duration: auto``).

Oracles: the momentum of the reference state (zero, by Kraiem 2022 (4.51)); Pinocchio's ABA, which
must turn the reference torques back into the reference accelerations (an independent algorithm from
the CRBA + RNEA the planner uses); the exact time-scaling of rigid dynamics with no external force
(τ ∝ 1/T², q̇ ∝ 1/T)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from sms_cli.mission.load import load_mission
from sms_cli.model import compile_system
from sms_cli.sim.authority import (plan_moves, reference_dynamics, resolve_durations, segment_demand,
                                   shortest_duration, zero_momentum_rates)
from sms_cli.sim.metrics import relative_rate_error
from conftest import run_cli

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def pulsar():
    loaded = load_mission(ROOT / "missions" / "pulsar_simple.yaml")
    return loaded, compile_system(loaded)


@pytest.fixture(scope="module")
def caldera():
    loaded = load_mission(ROOT / "missions" / "caldera_s2_arm.yaml")
    return loaded, compile_system(loaded)


def _random_state(sm, rng):
    q = sm.q0.copy()
    q[sm.idx.q_arm] += rng.uniform(-0.5, 0.5, len(sm.arm))
    return q, rng.normal(size=len(sm.arm)) * 0.1, rng.normal(size=len(sm.arm)) * 0.05


@pytest.mark.parametrize("case", ["pulsar", "caldera"])
def test_reference_state_has_zero_momentum_and_a_still_base(case, request):
    """4 wheels in a 54.74° pyramid (pulsar) and 3 orthogonal ones (Caldera 2019): ω = 0, momentum 0."""
    _, sm = request.getfixturevalue(case)
    rng = np.random.default_rng(3)
    for _ in range(5):
        q, qd, _ = _random_state(sm, rng)
        v = zero_momentum_rates(sm, q, qd)
        assert np.all(v[sm.idx.base_angular] == 0.0)
        assert np.allclose(v[sm.idx.arm], qd)
        p, k, _ = sm.momenta(q, v)
        scale = np.linalg.norm(sm.rigid_mass_matrix(q) @ v)
        assert np.linalg.norm(p) < 1e-12 * scale and np.linalg.norm(k) < 1e-12 * scale


@pytest.mark.parametrize("case", ["pulsar", "caldera"])
def test_reference_torques_give_back_the_reference_accelerations_in_aba(case, request):
    """ABA(q, v, τ) = a: the base (no wrench applied) does not rotate, the arm follows q̈_d."""
    _, sm = request.getfixturevalue(case)
    rng = np.random.default_rng(5)
    d = pin.Data(sm.model)
    for _ in range(5):
        q, qd, qdd = _random_state(sm, rng)
        v, a, tau = reference_dynamics(sm, q, qd, qdd)
        assert np.all(tau[:6] == 0.0) or np.max(np.abs(tau[:6])) < 1e-9 * np.max(np.abs(tau))
        tau_applied = tau.copy()
        tau_applied[:6] = 0.0
        a_aba = pin.aba(sm.model, d, q, v, tau_applied)
        assert np.max(np.abs(a_aba - a)) < 1e-9 * max(1.0, np.max(np.abs(a)))
        assert np.max(np.abs(a_aba[sm.idx.base_angular])) < 1e-9 * np.max(np.abs(a))


def test_demand_scales_exactly_with_the_duration(pulsar):
    """Torque peaks ∝ 1/T², rate peaks ∝ 1/T, base acceleration ∝ 1/T² (rigid, no external force)."""
    _, sm = pulsar
    a0 = sm.q0[sm.idx.q_arm].copy()
    a1 = a0 + np.array([2.0, math.radians(60), 0, 0, 0])
    one = segment_demand(sm, sm.q0, a0, a1, samples=21)
    T = 37.0
    direct = segment_demand(sm, sm.q0, a0, a1, samples=21, duration=T)
    for name, tau in one.torque.items():
        assert direct.torque[name] == pytest.approx(tau / T**2, rel=1e-9, abs=1e-15)
        assert direct.rate[name] == pytest.approx(one.rate[name] / T, rel=1e-9, abs=1e-15)
    assert direct.base_acceleration == pytest.approx(one.base_acceleration / T**2, rel=1e-9)


def test_shortest_duration_puts_the_limiting_actuator_exactly_at_its_limit(pulsar):
    _, sm = pulsar
    a0 = sm.q0[sm.idx.q_arm].copy()
    a1 = a0 + np.array([0, 0, -math.radians(45), math.radians(30), 0])
    dem = segment_demand(sm, sm.q0, a0, a1, samples=41)
    for frac in (1.0, 0.5):
        T, why = shortest_duration(sm, dem, torque_fraction=frac)
        name, kind = why.rsplit(" ", 1)
        limits = {w.name: (w.max_torque, w.max_speed) for w in sm.wheels}
        limits.update({j.name: (j.max_effort, j.max_velocity) for j in sm.arm})
        need = {n: dem.torque[n] / T**2 / limits[n][0] for n in limits if math.isfinite(limits[n][0])}
        assert kind == "torque" and need[name] == pytest.approx(frac, rel=1e-12)
        assert max(need.values()) <= frac * (1 + 1e-12)
        assert all(dem.rate[n] / T <= limits[n][1] for n in limits if math.isfinite(limits[n][1]))


def test_auto_phases_get_their_sized_segments_and_the_hold(pulsar):
    loaded, sm = pulsar
    spec = loaded.mission.simulation
    plans = plan_moves(sm, spec)
    resolved = resolve_durations(spec, plans)
    auto = spec.auto_duration
    for phase, out in zip(spec.phases, resolved.phases):
        if phase.duration != "auto":
            assert out == phase
            continue
        mine = [p for p in plans if p.phase == phase.name]
        times = np.cumsum([p.chosen_s for p in mine])
        assert [w.at for w in out.waypoints] == pytest.approx(list(times))
        assert out.duration == pytest.approx(times[-1] + auto.hold_after)
        for p in mine:
            assert p.chosen_s % auto.round_to == pytest.approx(0.0, abs=1e-9)
            assert p.torque_fraction <= auto.torque_fraction and p.speed_fraction <= auto.speed_fraction
            assert p.chosen_s - auto.round_to < p.shortest_s / math.sqrt(auto.torque_fraction) <= p.chosen_s
    assert {p.phase for p in plans} == {"transfer", "return"}
    # the tile is carried in the transfer and released for the return, and the model is left as it was
    assert plans[0].demand.torque["Spacecraft_to_RW1"] > 2 * plans[2].demand.torque["Spacecraft_to_RW1"]
    assert sm.payloads["tile"].attached


def test_relative_rate_error_is_kraiem_3_67():
    ref = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [1.0, 0.0]])
    act = np.array([[0.0, 0.0], [0.8, 0.3], [2.2, 0.1], [1.05, 0.0]])
    # max |q̇_d − q̇| = 0.2, over max |q̇_d| = 2 (not max |q̇| = 2.2); the still column is left out
    assert relative_rate_error(ref, act) == pytest.approx(0.2 / 2.0)
    assert relative_rate_error(np.zeros((3, 2)), act[:3]) is None


def test_compile_prints_the_move_table_and_flags_the_fast_transfer():
    r = run_cli("compile", ROOT / "missions" / "pulsar_fast_transfer.yaml")
    assert r.exit_code == 0, r.output
    rows = [ln for ln in r.stdout.splitlines() if "Spacecraft_to_RW1 torque" in ln]
    assert len(rows) == 4 and all("OVER A LIMIT" in ln for ln in rows)
    r = run_cli("compile", ROOT / "missions" / "pulsar_simple.yaml")
    rows = [ln for ln in r.stdout.splitlines() if "Spacecraft_to_RW1 torque" in ln]
    assert len(rows) == 4 and all(" auto " in ln and "OVER" not in ln for ln in rows)


@pytest.mark.parametrize("phase, message", [
    ({"name": "m", "duration": "auto"}, "has no waypoints"),
    ({"name": "m", "duration": "auto", "waypoints": [{"at": "5 s", "joints": {"arm_joint_1": 0.1}}]}, "take no 'at'"),
    ({"name": "m", "duration": "20 s", "waypoints": [{"joints": {"arm_joint_1": 0.1}}]}, "every waypoint needs 'at'"),
])
def test_auto_duration_input_errors(tmp_path, phase, message):
    import yaml

    f = tmp_path / "m.yaml"
    f.write_text(yaml.safe_dump({"extends": str(ROOT / "missions" / "pulsar_simple.yaml"),
                                 "simulation": {"phases": [phase]}}))
    r = run_cli("compile", f)
    assert r.exit_code == 2 and message in r.output and "Traceback" not in r.output
