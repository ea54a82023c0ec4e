"""Sensor noise and bias (``simulation.sensors``) in both engines: the measurement kernel
(``sms_cli.sim.compiled.sensors.measure_state``) against its closed form, the seeded stream's draws, and
whole missions with noisy, biased gyro, attitude and joint sensors on the general compiled loop and on the
NDI loop against ``engine: python`` (the reference): status, steps, metrics and recording to 1e-9."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from sms_cli.mission.load import load_mission
from sms_cli.model import compile_system
from sms_cli.sim.compiled import sensors as K
from sms_cli.sim.schema import NoiseSpec, SensorsSpec

ROOT = Path(__file__).resolve().parents[1]
NOISY = {"seed": 11, "gyro": {"noise": 2.0e-4, "bias": [1.0e-4, -3.0e-4, 2.0e-4]},
         "attitude": {"noise": 1.0e-4, "bias": [2.0e-4, 0, -1.0e-4]}, "joints": {"noise": 1.0e-4, "bias": 5.0e-5}}


@pytest.fixture(scope="module")
def caldera():
    return compile_system(load_mission(ROOT / "missions" / "caldera_s2_arm.yaml"))


def test_one_draw_of_ticks_by_k_is_ticks_successive_draws():
    """numpy's Generator: one (ticks × K) draw of normals gives the numbers of ticks successive draws of
    3, 3, n, n (the Python loop's per-tick order), so the compiled loops can draw a slice of ticks at once."""
    n, ticks = 5, 40
    block = np.random.default_rng(123).standard_normal((ticks, 6 + 2 * n))
    rng = np.random.default_rng(123)
    rows = [np.concatenate([rng.standard_normal(3), rng.standard_normal(3), rng.standard_normal(n), rng.standard_normal(n)])
            for _ in range(ticks)]
    assert np.array_equal(block, np.array(rows))


def _hamilton(a, b):
    """a ⊗ b (xyzw) by Pinocchio's quaternions."""
    return (pin.Quaternion(np.asarray(a, float)) * pin.Quaternion(np.asarray(b, float))).coeffs()


@pytest.mark.parametrize("gyro, att, joints", [((2e-3, [1e-3, -2e-3, 3e-3]), (1e-2, [0.02, -0.01, 0.03]), (1e-3, 4e-4)),
                                               ((0.0, 1e-3), (0.0, [0.3, -0.2, 0.1]), (1e-3, 0.0)),
                                               ((1e-3, 0.0), (0.0, 0.0), (0.0, [1e-3, 2e-3, -1e-3]))])
def test_measure_state_is_the_formula(caldera, gyro, att, joints):
    """ω + b + σn, q ⊗ exp(b + σn) (Pinocchio's exp3_quat and quaternion product) and the arm's angles and rates
    + b + σn, the normals taken in the order gyro, attitude, angles, rates for the sensors with σ > 0 only; the
    other coordinates copied; an unperturbed attitude (no σ, no bias) copied exactly."""
    sm = caldera
    rng = np.random.default_rng(4)
    spec = SensorsSpec(gyro=NoiseSpec(noise=gyro[0], bias=gyro[1]), attitude=NoiseSpec(noise=att[0], bias=att[1]),
                       joints=NoiseSpec(noise=joints[0], bias=joints[1]))
    n = len(sm.arm)
    arm_q = np.array([a.q_index for a in sm.arm], dtype=np.int64)
    arm_v = np.array([a.v_index for a in sm.arm], dtype=np.int64)
    par, width = K.sensor_parameters(spec, n), K.noise_width(spec, n)
    assert width == 3 * (gyro[0] > 0) + 3 * (att[0] > 0) + 2 * n * (joints[0] > 0)
    for _ in range(3):
        q = pin.integrate(sm.model, sm.q0, rng.normal(scale=0.5, size=sm.nv))
        v = rng.normal(size=sm.nv)
        noise = rng.normal(size=width)
        q_s, v_s = np.empty(sm.nq), np.empty(sm.nv)
        K.measure_state(par, noise, arm_q, arm_v, q, v, q_s, v_s)
        cols = iter(noise)
        take = lambda k, sigma: np.array([next(cols) for _ in range(k)]) if sigma > 0 else np.zeros(k)  # noqa: E731
        w = v.copy()
        w[3:6] = v[3:6] + np.broadcast_to(gyro[1], 3) + gyro[0] * take(3, gyro[0])
        r = np.broadcast_to(att[1], 3) + att[0] * take(3, att[0])
        p = q.copy()
        if np.any(r != 0):
            p[3:7] = _hamilton(q[3:7], pin.exp3_quat(r))
        p[arm_q] = q[arm_q] + np.broadcast_to(joints[1], n) + joints[0] * take(n, joints[0])
        w[arm_v] = v[arm_v] + np.broadcast_to(joints[1], n) + joints[0] * take(n, joints[0])
        assert np.abs(q_s - p).max() <= 1e-14 and np.abs(v_s - w).max() <= 1e-14
        if att == (0.0, 0.0):
            assert np.array_equal(q_s[3:7], q[3:7])


def test_python_sensors_draw_each_tick_in_order(caldera):
    """``Sensors.measure`` (the Python loop) draws per tick 3 gyro, 3 attitude, n angle and n rate normals from
    default_rng(seed) and measures ω, the attitude, the joints and q, v as the formula says (numpy, Pinocchio);
    the wheel speeds, the position and the modes are not perturbed."""
    from sms_cli.sim.sensors import Sensors

    sm = caldera
    spec = SensorsSpec.model_validate(NOISY)
    sens = Sensors(sm, spec)
    rng = np.random.default_rng(NOISY["seed"])
    n = len(sm.arm)
    arm_q = [a.q_index for a in sm.arm]
    st = np.random.default_rng(9)
    for tick in range(4):
        q = pin.integrate(sm.model, sm.q0, st.normal(scale=0.3, size=sm.nv))
        v = st.normal(size=sm.nv)
        s = sens.measure(0.1 * tick, q, v, np.zeros(0), np.zeros(0))
        g, a, jq, jv = rng.standard_normal(3), rng.standard_normal(3), rng.standard_normal(n), rng.standard_normal(n)
        omega = v[3:6] + np.array(NOISY["gyro"]["bias"]) + NOISY["gyro"]["noise"] * g
        quat = _hamilton(q[3:7], pin.exp3_quat(np.array(NOISY["attitude"]["bias"]) + NOISY["attitude"]["noise"] * a))
        q_arm = q[arm_q] + NOISY["joints"]["bias"] + NOISY["joints"]["noise"] * jq
        qd_arm = v[sm.idx.arm] + NOISY["joints"]["bias"] + NOISY["joints"]["noise"] * jv
        for got, want in ((s.omega, omega), (s.quat, quat), (s.q_arm, q_arm), (s.qd_arm, qd_arm), (s.q[3:7], quat),
                          (s.v[3:6], omega), (s.q[arm_q], q_arm), (s.v[sm.idx.arm], qd_arm)):
            assert np.abs(np.asarray(got) - want).max() <= 1e-14
        assert np.array_equal(s.wheel_speed, v[sm.idx.wheels]) and np.array_equal(s.position, q[:3])
        assert np.allclose(s.velocity, pin.Quaternion(quat).toRotationMatrix() @ v[:3], rtol=0, atol=1e-14)


def _sensors_yaml() -> str:
    return "  sensors: " + json.dumps(NOISY) + "\n"


# caldera_s2_arm shortened: a slew held by the attitude law (mrp_feedback on the SystemModel's body), the arm's
# computed torque on its model (M*, h* from the measured state), a phase that settles early (the next one's
# normals continue the stream where the settled one stopped), a joint move
ARM_PHASES = """  phases:
    - {name: slew, kind: slew, duration: 2 s, attitude: [0.5 deg, -0.3 deg, 0.2 deg]}
    - {name: settle, kind: hold, duration: 3 s, until_settled: 0.05, settle_time: 0.3 s}
    - {name: move, kind: deploy, duration: 2 s, waypoints: [{at: 2 s, joints: {joint_1: 0.3, joint_2: 0.2, joint_3: -0.1}}]}
"""


def test_general_loop_with_noisy_sensors_equals_the_python_loop(tmp_path, caldera):
    """caldera_s2_arm (shortened) with noisy, biased gyro, attitude and joint sensors: the compiled loop and the
    Python loop agree on status, steps, metrics, conservation and every recorded message (1e-9); the noise
    changed the run (the same mission without it ends elsewhere), and the settling phase ended early."""
    from test_compiled_arm import _compare_missions_text

    text = lambda e, sensors=True: (f"extends: {ROOT / 'missions' / 'caldera_s2_arm.yaml'}\nname: noisy_{e}\n"  # noqa: E731
                                    f"simulation:\n  engine: {e}\n" + (_sensors_yaml() if sensors else "") + ARM_PHASES)
    py, _ = _compare_missions_text(tmp_path, text)
    assert py["phases"][1]["duration_s"] < 2.9  # settled early: the stream's rewind matters
    from test_compiled_engine import _run

    quiet, _ = _run(tmp_path, text("compiled", sensors=False), "quiet")
    assert abs(quiet["overall"]["attitude_error_rad"]["max"] - py["overall"]["attitude_error_rad"]["max"]) > 1e-6


def test_general_loop_measures_for_the_laws_and_traces_the_true_state(caldera):
    """The compiled loop's trace with noisy sensors on held-base and end-effector phases (chevallard_deploy_track,
    shortened): the held base's reaction and the end-effector error come from the true state, the resolved rate
    and the arm law see the measured one; the whole trace equal to the Python loop's (1e-9)."""
    from sms_cli.sim.engine import Simulation

    loaded = load_mission(ROOT / "missions" / "chevallard_deploy_track.yaml")
    spec = loaded.mission.simulation
    phases = [p.model_copy(update={"duration": min(p.duration, 1.5)}) for p in spec.phases]
    assert any(p.base_mode == "fixed" for p in phases) and any(p.end_effector is not None for p in phases)
    spec = spec.model_copy(update={"phases": phases, "sensors": SensorsSpec.model_validate(NOISY)})
    traces = {}
    for engine in ("python", "compiled"):
        sm = compile_system(loaded)
        res = Simulation(sm, spec.model_copy(update={"engine": engine}), None, progress=False).run()
        assert res.timing["engine"] == engine and res.status == "completed"
        traces[engine] = res.trace
    a, b = traces["python"], traces["compiled"]
    assert np.isfinite(a["ee_err"]).any() and np.isfinite(a["base_reaction"]).any()
    for k, x in a.items():
        x, y = np.asarray(x, float), np.asarray(b[k], float)
        assert x.shape == y.shape, k
        assert np.array_equal(np.isnan(x), np.isnan(y)), k
        assert np.nan_to_num(np.abs(x - y)).max(initial=0.0) <= 1e-9 * max(1.0, np.nanmax(np.abs(x), initial=0.0)), k


def test_same_seed_same_trace_other_seed_other_trace(caldera):
    """The compiled loop's run is a function of the seed: the same seed twice gives the same trace bit for bit,
    another seed another trace."""
    from sms_cli.sim.engine import Simulation

    loaded = load_mission(ROOT / "missions" / "caldera_s2_arm.yaml")
    spec = loaded.mission.simulation
    phases = [p.model_copy(update={"duration": min(p.duration, 1.0)}) for p in spec.phases[:2]]

    def trace(seed):
        s = spec.model_copy(update={"phases": phases, "engine": "compiled",
                                    "sensors": SensorsSpec.model_validate(dict(NOISY, seed=seed))})
        return Simulation(compile_system(loaded), s, None, progress=False).run().trace

    a, b, c = trace(1), trace(1), trace(2)
    for k in ("att_err", "wheel_torque", "joint_torque", "momentum"):
        assert np.array_equal(a[k], b[k]), k
    assert not np.array_equal(a["joint_torque"], c["joint_torque"])


# the flagship's phases, shortened to a few seconds: a hold that settles early, a joint move with the tile, its
# release, a hold
FLAGSHIP = """    - {name: hold, kind: hold, duration: 2 s, attitude: [0, 0, 0], until_settled: 0.05, settle_time: 0.3 s}
    - {name: transfer, kind: move_payload, duration: 2 s, waypoints: [{at: 2 s, joints: {rail_joint_1: 1.0e-4, arm_joint_1: 2.0e-5}}]}
    - {name: release, kind: release, duration: 0.5 s, detach: [tile]}
    - {name: settle, kind: hold, duration: 1 s}
"""


def test_ndi_loop_with_noisy_sensors_equals_the_python_loop(tmp_path):
    """The flagship (NDI + observer, 10 modes, the tile released) with noisy, biased gyro, attitude and joint
    sensors: the NDI loop and the Python loop agree on status, steps, metrics, conservation and every recorded
    message (1e-9); the first phase settled early."""
    from test_compiled_arm import _compare_missions_text
    from test_compiled_ndi import _gains, _mission_text

    gains = _gains(compile_system(load_mission(ROOT / "missions" / "pulsar_simple.yaml")))
    text = lambda e: _mission_text("pulsar_simple.yaml", e, FLAGSHIP, gains).replace(  # noqa: E731
        "simulation:\n", "simulation:\n" + _sensors_yaml(), 1)
    py, _ = _compare_missions_text(tmp_path, text)
    assert py["phases"][0]["duration_s"] < 1.9
    assert py["overall"]["attitude_error_rad"]["max"] > 0


def test_a_dispersion_campaign_run_picks_the_compiled_engine():
    """A run of campaign_pulsar_dispersions (its gyro bias dispersed, the other dispersions nominal) on
    ``engine: auto``: the compiled NDI loop runs it, no longer the Python loop."""
    from sms_cli.campaign.dispersions import draws
    from sms_cli.sim.engine import Simulation

    loaded = load_mission(ROOT / "missions" / "campaign_pulsar_dispersions.yaml")
    c = loaded.mission.campaign
    run = draws(c, c.entropy, [0])[0]
    bias = [run[f"gyro_bias_{a}"] for a in "xyz"]
    assert all(0 < abs(b) <= 1e-3 for b in bias)  # rad/s, absolute: the nominal bias is 0
    from test_compiled_ndi import _gains

    sm = compile_system(loaded)
    spec = loaded.mission.simulation
    spec = spec.model_copy(update={"sensors": spec.sensors.model_copy(update={"gyro": NoiseSpec(bias=bias)}),
                                   "ndi": spec.ndi.model_copy(update=_gains(sm))})  # the gains `sms synthesize` writes
    assert spec.engine == "auto"
    sim = Simulation(sm, spec, None, progress=False)
    assert sim.compiled_unsupported() is None and sim.compiled_loop


@pytest.mark.parametrize("case", ["momentum_free_flying", "thrusters_cube"])
def test_momentum_laws_and_real_thrusters_with_noisy_sensors_equal_the_python_loop(tmp_path, case):
    """A momentum law (free_flying: its wheel torques and base wrench from the measured q, v) and an attitude law
    driving real thrusters (the allocation's probe call and the firing call measure the same tick's state) with a
    noisy, biased gyro and attitude: the compiled loop's trace and metrics equal the Python loop's (1e-9)."""
    from test_compiled_momentum import _assert_traces_equal, _traces

    text = (ROOT / "tests" / "data" / f"{case}.yaml").read_text().replace("../../missions/", f"{ROOT / 'missions'}/")
    for name in ("momentum_ff_wheels",):  # the file momentum_free_flying extends
        (tmp_path / f"{name}.yaml").write_text((ROOT / "tests" / "data" / f"{name}.yaml").read_text().replace(
            "../../missions/", f"{ROOT / 'missions'}/"))
    sensors = {k: NOISY[k] for k in ("seed", "gyro", "attitude")}
    path = tmp_path / "case.yaml"
    path.write_text(text.replace("simulation:\n", "simulation:\n  sensors: " + json.dumps(sensors) + "\n", 1))
    _assert_traces_equal(_traces(path, duration=4.0), momentum=case.startswith("momentum"))


def test_a_joint_bias_of_another_length_than_the_arm_is_an_input_error_with_its_line(tmp_path):
    """Three bias values on an arm of another number of joints: exit 2 at the bias's line, not numpy's error."""
    from typer.testing import CliRunner

    from sms_cli.cli import app

    mission = tmp_path / "m.yaml"
    mission.write_text(f"extends: {ROOT / 'missions' / 'chevallard_deploy_track.yaml'}\nsimulation:\n  sensors:\n"
                       "    joints:\n      bias: [0.1, 0.1, 0.1]\n")
    r = CliRunner().invoke(app, ["simulate", str(mission), "-o", str(tmp_path / "out")])
    assert r.exit_code == 2, r.output
    assert "m.yaml:5" in r.output and "the joint sensors' bias has 3 values" in r.output and "Traceback" not in r.output
