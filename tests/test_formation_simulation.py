"""Two-spacecraft missions (Vicariotto 2023 ch. 5) end to end: the relative law's Lyapunov identity, momentum
through internal wrenches, the shipped S4/S6 missions through the CLI, and bad input."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from sms_cli.cli import app
from sms_cli.mission.load import load_mission, load_mission_text

ROOT = Path(__file__).resolve().parents[1]
S6 = ROOT / "missions" / "vicariotto_s6_relative_hil.yaml"
S4 = ROOT / "missions" / "vicariotto_s4_relative_free_flying.yaml"
runner = CliRunner()


def _variant(base: Path, extra: str, tmp_path: Path):
    """A mission extending ``base`` with ``extra`` YAML (written next to the shipped missions' folder)."""
    text = f"extends: {base}\n{extra}"
    return load_mission_text(text, base_dir=base.parent, name=f"variant_{tmp_path.name}.yaml")


def _simulation(loaded):
    from sms_cli.formation.simulate import FormationSimulation
    from sms_cli.formation.stage import prepared

    servicer, client = prepared(loaded)
    return FormationSimulation(loaded.mission, servicer, client, None, progress=False)


def _W_rate_identity(sim, q, v):
    """(dW/dt by a central difference of the plant under the law's inputs at (q, v), the law's closed form
    −V_LᵀK_LV_L − V_EᵀK_EV_E − K_w|θ̇|²)."""
    p = sim.plant
    dec, b1, b2, _ = sim.body_states(q, v)
    cmd = sim.law(dec, b1, b2)
    assert not cmd.saturated
    tau = np.zeros(p.model.nv)
    tau[p.bodies[0].wheels_v] = cmd.tau_w1
    tau[p.bodies[1].wheels_v] = cmd.tau_w2
    h = 1e-3
    Ws = []
    for dt in (h, -h):
        qn, vn = p.step(q, v, dt, tau, (cmd.F1, cmd.F2))
        d, c1, c2, _ = sim.body_states(qn, vn)
        Ws.append(sim.law(d, c1, c2).lyapunov)
    V_L, V_E = dec.locked_shape(b1.xi, b2.xi)
    law = sim.law
    predicted = (-(V_L @ (law.locked.kd * V_L) if law.locked.controlled else 0.0)
                 - (V_E @ (law.shape.kd * V_E) if law.shape.controlled else 0.0)
                 - law.wheel_damping * (b1.wheel_rates @ b1.wheel_rates + b2.wheel_rates @ b2.wheel_rates))
    if law.hierarchical:  # the attitude springs act through the wheels only: their power on V_L, V_E remains
        rot = lambda e: np.concatenate([np.zeros(3), e.grad[3:]])  # noqa: E731
        predicted += V_L @ rot(cmd.locked_error) + V_E @ (rot(cmd.shape_error) - dec.A_star.T @ rot(cmd.locked_error))
    return (Ws[0] - Ws[1]) / (2 * h), predicted


def _perturbed_state(sim, seed: int):
    import pinocchio as pin

    rng = np.random.default_rng(seed)
    q = pin.integrate(sim.plant.model, sim.q, 0.05 * rng.standard_normal(sim.v.size))  # off both setpoints
    v = sim.v.copy()
    v += 0.01 * rng.standard_normal(v.size)
    for b in sim.plant.bodies:
        v[b.wheels_v] = 20.0 * rng.standard_normal(len(b.wheels_v))  # wheels spinning: Λθ̇ terms matter
    return q, v


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_lyapunov_rate_equals_the_dissipation_of_the_free_flying_law(seed):
    """Ẇ = −V_LᵀK_LV_L − V_EᵀK_EV_E − K_w|θ̇|² exactly (both subsystems controlled, wheels spinning): W is the
    kinetic energy of the pair plus both potentials, so this checks the law's every term against the dynamics."""
    sim = _simulation(load_mission(S4))
    sim.law.wheel_damping = 1e-3
    q, v = _perturbed_state(sim, seed)
    measured, predicted = _W_rate_identity(sim, q, v)
    assert predicted < 0
    assert measured == pytest.approx(predicted, rel=1e-5, abs=1e-12)


@pytest.mark.parametrize("seed", [3, 4])
def test_lyapunov_rate_of_the_hierarchical_law(seed, tmp_path):
    """The hierarchical law (thrusters without the attitude springs): Ẇ = dissipation + the attitude springs' power
    on the locked and shape twists, exactly."""
    sim = _simulation(_variant(S4, "formation: {relative_law: hierarchical}\n", tmp_path))
    sim.law.wheel_damping = 1e-3
    q, v = _perturbed_state(sim, seed)
    measured, predicted = _W_rate_identity(sim, q, v)
    assert measured == pytest.approx(predicted, rel=1e-5, abs=1e-12)


def test_hierarchical_law_turns_the_relative_attitude_with_the_wheels(tmp_path):
    """S6 under the hierarchical law with the wheels' attitude gain (kp_angular 3000 N m/rad: the wheels act through
    Λ ≈ 1.3e-4): the relative pose still converges, and the wheels did the turning."""
    loaded = _variant(S6, "formation: {relative_law: hierarchical, pushes: [], duration: 200 s, "
                          "shape: {kp_angular: [3000, 3000, 3000]}}\n", tmp_path)
    result = _simulation(loaded).run()
    tr = result.trace
    assert np.degrees(tr["shape_angle"][-1]) < 0.05 and np.linalg.norm(tr["shape_position"][-1]) < 2e-3
    assert np.max(np.abs(tr["wheels1"])) > 1.0 and np.max(np.abs(tr["tau_w1"])) > 1e-3


def test_kinetic_energy_split_equals_the_plant_energy():
    """T = ½V_LᵀM_LV_L + ½V_EᵀM_EV_E + Σ½θ̇ᵀM_θθ̇ (Vicariotto 2023 §5.3) equals Pinocchio's kinetic energy."""
    sim = _simulation(load_mission(S4))
    q, v = _perturbed_state(sim, 5)
    dec, b1, b2, _ = sim.body_states(q, v)
    T_L, T_E = dec.energies(*dec.locked_shape(b1.xi, b2.xi))
    T_w = sum(0.5 * b.wheel_rates @ b.wheel_inertia @ b.wheel_rates for b in (b1, b2))
    assert T_L + T_E + T_w == pytest.approx(sim.plant.kinetic_energy(q, v), rel=1e-12)


def test_initial_state_has_the_requested_locked_and_shape_twists():
    sim = _simulation(load_mission(S6))
    dec, b1, b2, _ = sim.body_states(sim.q, sim.v)
    V_L, V_E = dec.locked_shape(b1.xi, b2.xi)
    assert np.allclose(V_L, [0, 0, 0, 0, 0.02, 0], atol=1e-14)
    assert np.allclose(V_E, [0.01, 0, 0, 0, 0.02, 0], atol=1e-14)


def test_internal_shape_pair_conserves_total_momentum(tmp_path):
    """Only the shape pair and the wheels act (actuation: both, no pushes): total momentum to 1e-9 relative."""
    loaded = _variant(S6, "formation: {duration: 40 s, pushes: []}\n", tmp_path)
    result = _simulation(loaded).run()
    H = result.trace["H_world"]
    assert np.max(np.abs(H - H[0])) <= 1e-9 * np.max(np.abs(H))
    assert np.max(np.abs(result.trace["F_E"])) > 0.01  # the law did act


def test_one_sided_actuation_moves_the_locked_system(tmp_path):
    """actuation: other puts the whole shape wrench on one spacecraft: its wrench is then external to the pair."""
    loaded = _variant(S6, "formation: {duration: 20 s, pushes: [], actuation: servicer}\n", tmp_path)  # = other
    result = _simulation(loaded).run()
    assert np.max(np.abs(result.trace["F1"])) == 0.0
    H = result.trace["H_world"]
    assert np.max(np.abs(H - H[0])) > 1e-4 * np.max(np.abs(H))


def test_s6_through_the_cli(tmp_path):
    out = tmp_path / "s6"
    r = runner.invoke(app, ["run", str(S6), "-o", str(out)])
    assert r.exit_code == 0, r.output
    res = json.loads((out / "results.json").read_text())
    sim = res["simulate"]
    assert sim["formation"] == {"master": "client", "other": "servicer", "relative_motion": "relative_motion.csv"}
    assert sim["shape"]["position_error_final_m"] < 0.02 and sim["shape"]["angle_error_final_deg"] < 1.0
    assert (out / "relative_motion.csv").read_text().splitlines()[0].startswith("t,p1_x,p1_y,p1_z,q1_x")
    assert "pair" in res["compile"] and res["compile"]["client"]["total_mass_kg"] == pytest.approx(300.0)
    html = (out / "report.html").read_text()
    assert "Two-spacecraft simulation" in html and "Relative (shape) error" in html
    from mcap.reader import make_reader

    with open(out / "simulation.mcap", "rb") as f:
        reader = make_reader(f)
        topics = {c.topic for c in reader.get_summary().channels.values()}
        robot = next(m for _, _, m in reader.iter_messages(topics=["/robot_description"]))
        timing = next(m.metadata for m in reader.iter_metadata() if m.name == "sms.timing")
        run = next(m.metadata for m in reader.iter_metadata() if m.name == "run")
    assert run["steps"] == str(sim["steps"]) == "6000"  # 300 s at dt 0.05 s: every plant step, not the samples
    assert timing["replayable"] == "no" and "internal shape pair" in timing["not_replayable_because"]
    assert {"/tf", "/locked/twist", "/shape/twist", "/momentum/total", "/momentum/relative", "/energy"} <= topics
    assert b"client/bus" in robot.data and b"servicer/bus" in robot.data
    # the HIL export of the run (formation.facility): g1_HW⁻¹ g2_HW = g12 at every sample (Vicariotto 2023 (6.2))
    import csv

    import pinocchio as pin

    rel = np.loadtxt(out / "relative_motion.csv", delimiter=",", skiprows=1)
    rows = list(csv.DictReader(open(out / "hil" / "commands.csv")))
    pose = lambda r: pin.XYZQUATToSE3(np.array([float(r[k]) for k in ("x", "y", "z", "qx", "qy", "qz", "qw")]))
    moving = [pose(r) for r in rows if r["role"] == "moving"]
    held = pose(next(r for r in rows if r["role"] == "held"))
    assert len(moving) == rel.shape[0]
    for k, g1_hw in enumerate(moving):
        g12 = pin.XYZQUATToSE3(rel[k, 1:8]).actInv(pin.XYZQUATToSE3(rel[k, 8:15]))
        assert np.max(np.abs((g1_hw.actInv(held)).homogeneous - g12.homogeneous)) < 1e-12
    assert sim["hil"]["workspace"]["relative"]["inside_fraction"] == 1.0


def test_compile_summarises_both_spacecraft():
    r = runner.invoke(app, ["compile", str(S6)])
    assert r.exit_code == 0, r.output
    assert "mass 300.0000 kg, DoF base 6 · wheels 3" in r.output and "bases 3 m apart" in r.output
    assert "shape inertia M_E diagonal" in r.output


BAD = {
    "missing client URDF": ("client: {robot: {urdf: ../robots/nope.urdf}}\n", "nope.urdf: no such file"),
    "overlapping bodies": ("client: {pose: {position: [1.0, 0, 0]}}\n", "overlap"),
    "unknown master": ("formation: {master: chaser}\n", "formation.master"),
    "unknown actuation": ("formation: {actuation: chaser}\n", "formation.actuation"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_two_spacecraft_input_is_exit_2_with_its_line(case, tmp_path):
    extra, needle = BAD[case]
    path = tmp_path / "bad.yaml"
    path.write_text(f"extends: {S6}\n{extra}")
    r = runner.invoke(app, ["simulate", str(path), "-o", str(tmp_path / "out")])
    assert r.exit_code == 2, r.output
    assert needle in r.output and "bad.yaml:" in r.output.replace("\n", "")
    assert "Traceback" not in r.output


def test_formation_without_client_is_refused(tmp_path):
    path = tmp_path / "noclient.yaml"
    path.write_text("name: x\nrobot: {urdf: %s}\nformation: {duration: 1 s}\n" % (ROOT / "robots" / "vicariotto_servicer.urdf"))
    r = runner.invoke(app, ["simulate", str(path), "-o", str(tmp_path / "out")])
    assert r.exit_code == 2 and "client" in r.output


CAPTURE = ROOT / "missions" / "caldera_capture_tumbling.yaml"


def test_capture_keeps_momentum_and_joins_the_frames(tmp_path):
    """Through the capture only internal wrenches act: momentum after = before (1e-9 of what the interface exchanged);
    the joined frames end together (the interface is damped: ζ = 0.7 at 0.5 Hz)."""
    loaded = _variant(CAPTURE, "formation: {duration: 12 s}\n", tmp_path)
    sim = _simulation(loaded)
    result = sim.run()
    c = result.capture
    assert c["engaged"] and c["offset_m"] < 0.05
    assert c["linear_momentum_change_rel"] < 1e-9 and c["angular_momentum_change_rel"] < 1e-9
    assert c["linear_impulse_exchanged_Ns"] > 0.01  # the interface did act
    import pinocchio as pin

    from sms_cli.formation.capture import capture_offset

    pin.framesForwardKinematics(sim.plant.model, sim.capture.data, sim.final_q)
    d, a = capture_offset(sim.capture.data.oMf[sim.capture.frame_a], sim.capture.data.oMf[sim.capture.frame_b],
                          sim.capture.target)
    assert d < 0.1 * c["offset_m"] and a < 0.1 * c["offset_deg"]


@pytest.mark.parametrize("extra, code, needles", [
    ("formation: {capture: {at: 10 s}}\n", 3, ["capture time t = 10", "tolerance 0.05 m"]),
    ("formation: {capture: {natural_frequency: 25 Hz}}\n", 2, ["steps per period", "dt ≤"]),
    ("formation: {capture: {client_frame: grappel}}\n", 2, ["grappel", "did you mean 'grapple'"]),
    ("formation: {initial: {bodies: {chaser: {}}}}\n", 2, ["formation.initial.bodies is 'chaser'"]),
])
def test_capture_input_and_miss(extra, code, needles, tmp_path):
    path = tmp_path / "cap.yaml"
    path.write_text(f"extends: {CAPTURE}\n{extra}")
    r = runner.invoke(app, ["simulate", str(path), "-o", str(tmp_path / "out")])
    assert r.exit_code == code, r.output
    text = " ".join(r.output.split())
    for n in needles:
        assert n in text, text
    assert "Traceback" not in r.output
    if code == 2:
        assert "cap.yaml:" in text


def _positions(result) -> np.ndarray:
    return np.concatenate([result.trace["p1"], result.trace["p2"]], axis=1)


def test_decomposed_and_plain_simulations_of_a_mission_agree_to_fourth_order(tmp_path):
    """S4 (both subsystems controlled, momentum in both) with Vicariotto 2023's HIL integrator on [V_L; V_E; θ̇] and
    with the plain one on the absolute velocities: the same base trajectories, the difference shrinking ~16x when
    dt halves (both are 4th order). Measured: 1.6e-12 m at dt 0.05 s, 9.6e-14 m at 0.025 s over 20 s (ratio 16);
    at 0.0125 s round-off (5e-15 m) takes over."""
    diffs = []
    for dt in ("0.05 s", "0.025 s"):
        runs = [_simulation(_variant(S4, f"formation: {{duration: 20 s, dt: {dt}, integrator: {i}}}\n", tmp_path)).run()
                for i in ("plain", "decomposed")]
        diffs.append(np.max(np.abs(_positions(runs[0]) - _positions(runs[1]))))
    assert diffs[0] < 1e-9
    assert diffs[0] / diffs[1] > 8


def test_shape_reaches_its_setpoint_while_the_locked_system_spins(tmp_path):
    """S6 without pushes: the locked system spins at 0.02 rad/s throughout, and the shape still reaches its setpoint
    (the PD+ feed-forward C_EL V_L cancels the coupling; without it the shape rests 4 mm off, where the coupling
    balances the springs). The designed decay e^(−ζω_n t) = e^(−21) over 300 s leaves far below the 1 mm asserted."""
    result = _simulation(_variant(S6, "formation: {pushes: []}\n", tmp_path)).run()
    tr = result.trace
    assert np.linalg.norm(tr["shape_position"][-1]) < 1e-3
    assert np.min(np.linalg.norm(tr["V_L"][:, 3:], axis=1)) > 0.019  # the locked spin was there all along


def test_recorded_robot_description_is_one_valid_urdf_with_both_spacecraft():
    """The URDF the recording carries for Foxglove's 3D panel: both robots, prefixed, each hung from 'world' by a
    floating joint; it loads in Pinocchio, and every link it names is a frame the recording's /tf moves."""
    import pinocchio as pin

    from sms_cli.formation.stage import root_link
    from sms_cli.formation.urdf_pair import pair_urdf

    sim = _simulation(load_mission(CAPTURE))
    text = pair_urdf([(b.name, b.system.urdf_text, root_link(b.system)) for b in sim.plant.bodies])
    model = pin.buildModelFromXML(text)
    links = {f.name for f in model.frames if f.type == pin.FrameType.BODY}
    assert {"servicer/base_link", "servicer/ee_link", "client/bus", "client/grapple"} <= links
    assert [model.joints[j].shortname() for j in range(1, model.njoints)].count("JointModelFreeFlyer") == 2
    assert links - {"world", "universe"} <= set(sim.links.names)


def test_an_interrupted_two_spacecraft_run_keeps_what_ran(tmp_path, monkeypatch):
    """Ctrl-C at t ≈ 100 s: exit through KeyboardInterrupt after writing the section (status interrupted, the time
    reached), the CSV files and a finished, readable recording of the samples taken."""
    from mcap.reader import make_reader

    from sms_cli.formation import plant as plant_module
    from sms_cli.formation.stage import record_formation

    from sms_cli.sim.compiled import pair as pair_module

    calls = {"n": 0}

    def interrupting(real_step):
        def step(self, *a, **k):
            calls["n"] += 1
            if calls["n"] == 2000:  # t = 100 s at dt 0.05 s
                raise KeyboardInterrupt
            return real_step(self, *a, **k)

        return step

    for cls in (plant_module.TwoBodyPlant, pair_module.PairPlant):  # either engine's plant step
        monkeypatch.setattr(cls, "step", interrupting(cls.step))
    with pytest.raises(KeyboardInterrupt):
        record_formation(load_mission(S6), tmp_path, progress=False)
    sim = json.loads((tmp_path / "results.json").read_text())["simulate"]
    assert sim["status"] == "interrupted" and sim["t_end_s"] == pytest.approx(99.95, abs=0.2)
    rows = (tmp_path / "relative_motion.csv").read_text().splitlines()
    assert len(rows) - 1 == 500 or len(rows) - 1 == 501
    with open(tmp_path / "simulation.mcap", "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        run = next(m.metadata for m in reader.iter_metadata() if m.name == "run")
    tf = next(c.id for c in summary.channels.values() if c.topic == "/tf")
    assert summary.statistics.channel_message_counts[tf] == len(rows) - 1
    assert run["status"] == "interrupted" and run["steps"] == str(sim["steps"]) and 1990 <= sim["steps"] <= 2000


S6_THRUSTERS = ROOT / "missions" / "vicariotto_s6_thrusters.yaml"


def test_client_thrusters_burn_what_they_deliver_and_the_servicer_stays_passive(tmp_path, monkeypatch):
    """S6 with the client's thruster cube (actuation: client): the propellant used equals the delivered impulse of
    each thruster over F/(Isp g0) (the rocket flow, Table 3.1), the servicer feels no wrench, and the client's
    delivered wrench differs from the commanded one (the firing pattern's quantisation and minimum on-time)."""
    from sms_cli.thrusters import drive as drive_module

    import pinocchio as pin

    impulse, world_force = {}, []
    real = drive_module.step_drives

    def counting(drives, s, t, dt, advance):
        R1 = pin.XYZQUATToSE3(s[0][:7]).rotation  # the client (body 1) at the step's start
        out = real(drives, s, t, dt, advance)
        for d in drives:
            impulse[id(d)] = impulse.get(id(d), 0.0) + d.thrust_step * dt
            world_force.append(R1 @ (d.B[:3] @ d.thrust_step) * dt)
        return out

    monkeypatch.setattr(drive_module, "step_drives", counting)
    sim = _simulation(_variant(S6_THRUSTERS, "formation: {duration: 20 s, pushes: [], facility: null}\n", tmp_path))
    result = sim.run()
    (i, d), = sim.drives
    assert sim.plant.bodies[i].name == "client"
    expected = float(np.sum(impulse[id(d)] * d.ts.mass_flow / d.ts.max_force))
    assert d.used > 0.01 and d.used == pytest.approx(expected, rel=1e-12)
    assert np.all(result.trace["D2"] == 0.0) and np.all(result.trace["F2"] == 0.0)
    assert np.max(np.abs(result.trace["D1"] - result.trace["F1"])) > 0.1
    # the firings reach the plant: the pair's linear momentum changes by their impulse, world frame, to 2 % (the sum
    # takes the client's attitude at each step's start, and the ~1 kg of propellant burnt leaves with its momentum)
    H = result.trace["H_world"]
    expected_dp = np.sum(world_force, axis=0)
    assert np.linalg.norm(H[-1, :3] - H[0, :3] - expected_dp) < 0.02 * np.linalg.norm(expected_dp)


def test_the_python_api_says_where_two_spacecraft_missions_run(tmp_path):
    from sms_cli import api
    from sms_cli.errors import InputError

    with pytest.raises(InputError, match="two-spacecraft mission"):
        api.simulate(S6)
