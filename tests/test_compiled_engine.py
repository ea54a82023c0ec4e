"""The compiled engine (sms_cli/sim/compiled) against independent implementations.

- Kernels against Pinocchio on every shipped robot: forward dynamics (``pin.aba``), ``integrate``,
  frame poses (``framesForwardKinematics``), momentum and energy (SystemModel, i.e. Pinocchio's
  centroidal momentum and CRBA), parent-relative poses (frames.RelativePoses); the RKMK4 step
  against the Python integrator.
- The whole loop against the Python engine (the reference loop, every feature): the same
  trace, metrics and recording on the Basilisk scenario and on a mission made to exercise what
  the compiled loop implements (phases ended by settling, free-floating and free-flying phases,
  thrusters, wheel friction, the speed limiter, recording decimation, divergence).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from conftest import assert_tree_close

from sms_cli.recording.read import messages as read_messages
from sms_cli.errors import InputError
from sms_cli.mission.load import load_mission
from sms_cli.model import compile_system

ROOT = Path(__file__).resolve().parents[1]
ROBOT_MISSIONS = sorted(p.name for p in (ROOT / "missions").glob("*.yaml")
                        if "robot:" in p.read_text())


@pytest.fixture(scope="module", params=ROBOT_MISSIONS + ["tests/data/hub_hinge.yaml"])
def system(request):
    """Every shipped robot, and the hinged spring panel (joint springs)."""
    path = ROOT / request.param if "/" in request.param else ROOT / "missions" / request.param
    return compile_system(load_mission(path))


def _tree_args(T):
    return T.parent, T.kind, T.axis, T.place_R, T.place_p, T.inertia, T.armature, T.idx_q, T.idx_v


def test_kernels_equal_pinocchio(system):
    from sms_cli.sim.compiled import dynamics as D
    from sms_cli.sim.compiled.tree import flatten, frame_table
    from sms_cli.recording.frames import RelativePoses

    sm = system
    m = sm.model
    T = flatten(m)
    n = T.parent.size
    ws = D.workspace(n, m.nq, m.nv)
    rng = np.random.default_rng(7)
    for _ in range(5):
        q = pin.integrate(m, pin.neutral(m), rng.normal(size=m.nv))
        v, tau, th = rng.normal(size=m.nv), rng.normal(size=m.nv), 0.3 * rng.normal(size=m.nv)
        ref = pin.aba(m, m.createData(), q, v, tau)
        out = np.empty(m.nv)
        R_rel, p_rel = np.empty((n, 3, 3)), np.empty((n, 3))
        D.joint_transforms(T.kind, T.axis, T.place_R, T.place_p, T.idx_q, q, R_rel, p_rel)
        D.aba_call(T.parent, T.kind, T.axis, T.inertia, T.leaf_IA, T.armature, T.idx_v, R_rel, p_rel, v, tau, np.zeros((6, 6)),
                   np.zeros(6), out, ws)
        assert np.abs(out - ref).max() <= 1e-12 * max(1.0, np.abs(ref).max())
        qi = np.empty(m.nq)
        D.integrate(T.kind, T.axis, T.idx_q, T.idx_v, q, th, qi)
        assert np.abs(qi - pin.integrate(m, q, th)).max() <= 1e-14
        # momentum about the CoM and the origin, kinetic energy (rigid part: v only, no modes)
        me = np.empty(10)
        D.momenta_energy(T.parent, T.kind, T.axis, T.inertia, T.mass, T.com, T.armature, T.idx_v, R_rel, p_rel, v, me, ws)
        p, k_com, k_origin = sm.momenta(q, v, None)
        scale = max(1.0, np.abs(me[:9]).max())
        assert np.abs(me[:3] - p).max() <= 1e-12 * scale
        assert np.abs(me[3:6] - k_com).max() <= 1e-12 * scale
        assert np.abs(me[6:9] - k_origin).max() <= 1e-12 * scale
        assert me[9] == pytest.approx(0.5 * v @ sm.rigid_mass_matrix(q) @ v, rel=1e-12)
        # frame poses and parent-relative poses of every URDF link
        links = list(sm.link_parents)
        fids = [m.getFrameId(x) for x in links]
        oR, op = np.empty((n, 3, 3)), np.empty((n, 3))
        D.world_placements(T.parent, R_rel, p_rel, oR, op)
        poses = np.empty((len(fids), 7))
        D.frame_poses(oR, op, *frame_table(m, fids), poses)
        d = m.createData()
        pin.framesForwardKinematics(m, d, q)
        for i, f in enumerate(fids):
            M = d.oMf[f]
            assert np.abs(poses[i, :3] - M.translation).max() <= 1e-12
            assert np.abs(poses[i, 3:] - pin.Quaternion(M.rotation).coeffs()).max() <= 1e-12
        parents = [links.index(sm.link_parents[x]) if sm.link_parents[x] in links else -1 for x in links]
        rel = np.empty_like(poses)
        D.relative_poses(poses, np.array(parents, dtype=np.int64), rel)
        assert np.abs(rel - RelativePoses(parents, python_below=0)(poses)).max() <= 1e-14


def test_compiled_plant_step_equals_the_python_integrator(system):
    """One RKMK4 step (modes, springs when the robot has them) against the Python integrator with
    SystemModel.forward_dynamics (Pinocchio CRBA/NLE + the Schur complement on the modal block)."""
    from sms_cli.dynamics.integrator import State, rkmk4_step
    from sms_cli.sim.compiled.plant import CompiledPlant, unsupported_reason

    sm = system
    assert unsupported_reason(sm) is None  # every shipped robot fits the compiled plant
    rng = np.random.default_rng(3)
    plant = CompiledPlant(sm)
    for _ in range(3):
        q = pin.integrate(sm.model, sm.q0, 0.3 * rng.normal(size=sm.nv))
        s = State(q, 0.3 * rng.normal(size=sm.nv), 0.01 * rng.normal(size=sm.n_modes), 0.01 * rng.normal(size=sm.n_modes))
        tau = rng.normal(size=sm.nv)
        ref = rkmk4_step(sm.model, s, 0.02, lambda q_, v_, e, ed: sm.forward_dynamics(q_, v_, e, ed, tau))
        out = plant.step(s, tau, 0.02)
        assert np.abs(out.q - ref.q).max() <= 1e-13
        assert np.abs(out.v - ref.v).max() <= 1e-12 * max(1.0, np.abs(ref.v).max())
        if sm.n_modes:
            assert np.abs(out.eta - ref.eta).max() <= 1e-13 and np.abs(out.etadot - ref.etadot).max() <= 1e-12


# ----------------------------------------------------------------------------- the whole loop
EXERCISE = """\
extends: basilisk_rw_reference.yaml
name: compiled_engine_exercise
initial:
  base_angular_velocity: [0.0, 0.0, 0.0]
wheels:
  declared:
    - {name: RW1, axis: [1, 0, 0], position: [0, 0, 0], mass: 9.0, spin_inertia: 0.0796, transverse_inertia: 0.0398,
       max_torque: "0.2 N m", max_speed: "360 rpm", initial_speed: "100 rpm"}
    - {name: RW2, axis: [0, 1, 0], position: [0, 0, 0], mass: 9.0, spin_inertia: 0.0796, transverse_inertia: 0.0398,
       max_torque: "0.2 N m", max_speed: "360 rpm", initial_speed: "200 rpm"}
    - {name: RW3, axis: [0, 0, 1], position: [0, 0, 0], mass: 9.0, spin_inertia: 0.0796, transverse_inertia: 0.0398,
       max_torque: "0.2 N m", max_speed: "360 rpm", initial_speed: "300 rpm"}
simulation:
  dt: 0.05 s
  control_rate: 5 Hz
  record_rate: 3 Hz
  engine: ENGINE
  wheel_friction: {coulomb: 0.002, viscous: 0.0001}
  phases:
    - {name: slew, kind: slew, duration: 400 s, attitude: [0.2, -0.1, 0.3], until_settled: 2 deg, settle_time: 10 s}
    - {name: coast, kind: hold, duration: 30 s, base_mode: free-floating}
    - {name: thrust, kind: hold, duration: 40 s, base_mode: free-flying, attitude: [0, 0, 0]}
"""


def _run(tmp_path, text: str, name: str):
    from sms_cli.sim.stage import run_simulation

    path = tmp_path / f"{name}.yaml"
    path.write_text(text)
    loaded = load_mission(path)
    section = run_simulation(loaded, tmp_path / name, progress=False)
    return section, tmp_path / name


def _messages(mcap: Path) -> dict[str, list]:
    out: dict[str, list] = {}
    for topic, log_time, data in read_messages(mcap):
        out.setdefault(topic, []).append((log_time, data))
    return out


def _compare_runs(tmp_path, text_of):
    (py, py_dir), (cc, cc_dir) = (_run(tmp_path, text_of(e), e) for e in ("python", "compiled"))
    assert py["timing"]["engine"] == "python" and cc["timing"]["engine"] == "compiled"
    assert (py["status"], py["steps"]) == (cc["status"], cc["steps"])
    assert cc["t_end_s"] == py["t_end_s"]
    assert_tree_close(py["overall"], cc["overall"], "overall")
    assert_tree_close(py["phases"], cc["phases"], "phases")
    for k, x in py["conservation"].items():  # drifts are round-off on both sides: compare magnitudes
        y = cc["conservation"][k]
        if k.endswith("_abs") or k.endswith("_rel"):
            assert (x is None) == (y is None) and (x is None or abs(x - y) <= 1e-9 * max(1.0, abs(x))), k
        else:
            assert y == pytest.approx(x, rel=1e-9, abs=1e-9), k
    a, b = _messages(py_dir / "simulation.mcap"), _messages(cc_dir / "simulation.mcap")
    assert a.keys() == b.keys()
    for topic in a:
        assert [t for t, _ in a[topic]] == [t for t, _ in b[topic]], topic
        if topic == "/robot_description":
            assert [m for _, m in a[topic]] == [m for _, m in b[topic]], topic
            continue
        if topic == "/log":  # "<event> {details as JSON}": the details' numbers to round-off
            for (_, x), (_, y) in zip(a[topic], b[topic]):
                (hx, _, jx), (hy, _, jy) = x["message"].partition(" "), y["message"].partition(" ")
                assert {**x, "message": hx} == {**y, "message": hy}, topic
                assert_tree_close(json.loads(jx) if jx else jx, json.loads(jy) if jy else jy, f"{topic} {hx}")
            continue
        for (_, x), (_, y) in zip(a[topic], b[topic]):
            assert_tree_close(x, y, topic)
    return py, cc, a


def test_compiled_loop_equals_the_python_loop_on_the_basilisk_scenario(tmp_path):
    text = (ROOT / "missions" / "basilisk_rw_reference.yaml").read_text().replace("../robots/", str(ROOT / "robots") + "/")
    py, cc, msgs = _compare_runs(tmp_path, lambda e: text.replace("  record_rate: null", f"  record_rate: null\n  engine: {e}"))
    assert len(msgs["/tf"]) == 6001 and len(msgs["/tf"][0][1]["transforms"]) == 4


def test_compiled_loop_equals_the_python_loop_on_every_feature_it_implements(tmp_path):
    (tmp_path / "basilisk_rw_reference.yaml").write_text(
        (ROOT / "missions" / "basilisk_rw_reference.yaml").read_text().replace("../robots/", str(ROOT / "robots") + "/"))
    py, cc, msgs = _compare_runs(tmp_path, lambda e: EXERCISE.replace("ENGINE", e))
    slew, coast, thrust = py["phases"]
    assert slew["duration_s"] < 400.0  # ended by until_settled
    limit = 360 * np.pi / 30
    assert 0.999 * limit < slew["wheel_speed_peak_rad_s"] <= limit  # the speed limiter acted and held
    assert coast["attitude_torque_peak_Nm"] == 0.0 and thrust["attitude_torque_peak_Nm"] > 0.0
    times = np.array([t for t, _ in msgs["/attitude"]]) / 1e9
    assert np.allclose(np.diff(times)[1:-1], 1 / 3, atol=0.051)  # 3 Hz on a 0.05 s grid


def test_divergence_stops_both_engines_at_the_same_step(tmp_path):
    from sms_cli.errors import NumericalError

    (tmp_path / "basilisk_rw_reference.yaml").write_text(
        (ROOT / "missions" / "basilisk_rw_reference.yaml").read_text().replace("../robots/", str(ROOT / "robots") + "/"))
    results = {}
    for engine in ("python", "compiled"):
        text = EXERCISE.replace("ENGINE", engine).replace("  record_rate: 3 Hz", "  record_rate: 3 Hz\n  divergence: {max_rate: 33.0}")
        with pytest.raises(NumericalError):
            _run(tmp_path, text, engine)
        results[engine] = json.loads((tmp_path / engine / "results.json").read_text())["simulate"]
        events = [m for _, m in _messages(tmp_path / engine / "simulation.mcap")["/events"]]
        assert events[-1]["name"] == "diverged"
    assert results["python"]["t_end_s"] == results["compiled"]["t_end_s"]
    assert results["python"]["divergence"] == results["compiled"]["divergence"]


def test_engine_choice(tmp_path):
    from sms_cli.sim.engine import Simulation

    # a flexible panel on a mission whose phases hold the base fixed: the compiled loop refuses the combination
    path = tmp_path / "flexible.yaml"
    path.write_text(f"extends: {ROOT / 'missions' / 'chevallard_deploy_track.yaml'}\nname: flexible\nappendages:\n"
                    "  - {name: panel, link: base_link, modes: [{frequency: 0.5 Hz, damping: 0.005, "
                    "participation: [0, 0, 0, 0, 0, 2.0]}]}\n")
    loaded = load_mission(path)
    sm = compile_system(loaded)
    spec = loaded.mission.simulation
    with pytest.raises(InputError) as exc:
        Simulation(sm, spec.model_copy(update={"engine": "compiled"}), None, progress=False).run()
    assert "compiled engine cannot run this mission" in exc.value.render() and exc.value.exit_code == 2
    assert "a phase holds the base fixed on a model with flexible modes" in exc.value.render()
    assert Simulation(sm, spec, None, progress=False).compiled_unsupported() is not None


@pytest.mark.parametrize("law", ["quaternion_pd", "smc", "twisting_smc", "backstepping"])
def test_compiled_loop_equals_the_python_loop_on_each_attitude_law(tmp_path, law):
    """The compiled loop runs the Python loop's law kernels (sms_cli.sim.compiled.attitude_laws) with its
    own body quantities: the wheels' momentum (a constant inertia tensor, smc), the system's momentum
    about its CoM from the compiled kinematics against Pinocchio's (quaternion_pd's feedforward,
    backstepping's disturbance estimate), the compiled online J(q) and its difference quotient against
    Pinocchio's (backstepping), the memory of the integral and of the filtered σ̇ across phases.
    tests/data/compiled_law_*.yaml: slew (ended by settling), coast, thruster phase with a torque limit."""
    text = (ROOT / "tests" / "data" / f"compiled_law_{law}.yaml").read_text().replace(
        "extends: ../../missions/", f"extends: {ROOT / 'missions'}/")
    py, cc, msgs = _compare_runs(tmp_path, lambda e: text.replace("  record_rate: 2 Hz", f"  record_rate: 2 Hz\n  engine: {e}"))
    slew, coast, thrust = py["phases"]
    assert slew["attitude_torque_peak_Nm"] > 0.0 and coast["attitude_torque_peak_Nm"] == 0.0
    assert 0.0 < thrust["attitude_torque_peak_Nm"] <= 0.5  # the thrusters' limit
    if law != "twisting_smc":
        assert slew["duration_s"] < 150.0  # ended by until_settled
    assert len(msgs["/attitude"]) > 100


def test_the_compiled_loop_takes_the_online_inertia():
    """An ``online`` inertia runs compiled as J(q) and its central difference J̇ each tick (``loop.system_inertia``):
    accepted also once a rotor's inertia is not symmetric about its axis (J then varies with the wheel
    angles; tests/test_compiled_arm.py holds a J(q) that varies with the arm to the Python loop)."""
    from sms_cli.sim.compiled.runner import unsupported_reason

    loaded = load_mission(ROOT / "tests" / "data" / "compiled_law_backstepping.yaml")
    sm = compile_system(loaded)
    spec = loaded.mission.simulation
    assert spec.attitude.inertia == "online" and unsupported_reason(sm, spec, spec.attitude) is None
    Y = sm.model.inertias[sm.wheels[0].joint_id]
    sm.model.inertias[sm.wheels[0].joint_id] = pin.Inertia(Y.mass, Y.lever, np.diag([0.03, 0.05, 0.08]))
    assert unsupported_reason(sm, spec, spec.attitude) is None
    initial = spec.attitude.model_copy(update={"inertia": "initial"})
    assert unsupported_reason(sm, spec, initial) is None  # J(q0) is what the law asks for
    other = load_mission(ROOT / "missions" / "vicariotto_s3a_free_floating.yaml").mission.simulation.attitude
    assert unsupported_reason(sm, spec, other) is None  # the momentum laws run compiled (tests/test_compiled_momentum.py)
